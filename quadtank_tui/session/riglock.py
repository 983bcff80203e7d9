"""One rig, one lock, however its host is typed.

`localhost`, `LOCALHOST`, `127.0.0.1`, `::1`, `127.0.1.1` and this machine's own
name all reach the same Modbus server, so locking a rig under the host string as
typed (session.lock.device_key) would let two programs drive the same pumps.
Here the host is resolved first (getaddrinfo, every address of the name): each
address becomes one lock key, the loopback family and this machine's own
addresses collapse to one (`127.0.0.1`), and the rig is locked under all of its
keys, so a name with an IPv4 and an IPv6 address collides with either address
typed alone.  A name that does not resolve is refused: a lock under an
unresolved name would protect nothing.

A serial rig (the IST rig, daq/ist/) is one key: its device with the links
resolved (IstConfig.lock_key).  `rig_keys` and `RigLock.of` take either rig's
configuration: the one place the lock key of a rig is decided.

What this cannot see: a name that resolves to another address later (DNS changed
between two programs' starts), or two addresses that are the same device behind
a NAT.  A lab that renames its rigs keeps the names stable, or types addresses.
"""

from __future__ import annotations

import ipaddress
import socket
from datetime import datetime
from typing import TYPE_CHECKING

from quadtank_tui.session.lab import LabConfig
from quadtank_tui.session.lock import DaqLock, DaqLockHeld

if TYPE_CHECKING:
    from quadtank_tui.daq.config import DaqConfig
    from quadtank_tui.daq.ist.config import IstConfig

#: The key of every address that reaches this machine (loopback, own interfaces).
LOCAL = "127.0.0.1"


class RigNameError(ValueError):
    """The rig's host name does not resolve."""


def rig_addresses(host: str) -> tuple[str, ...]:
    """The canonical addresses of `host`, sorted: IPv4-mapped IPv6 as IPv4, IPv6
    compressed, this machine's addresses as LOCAL.  RigNameError if it does not resolve."""
    try:
        infos = socket.getaddrinfo(host.strip().lower(), None, type=socket.SOCK_STREAM)  # names are case-blind
    except (socket.gaierror, UnicodeError) as exc:
        why = exc.strerror if isinstance(exc, socket.gaierror) and exc.strerror else str(exc)
        raise RigNameError(f"the rig's host {host!r} does not resolve ({why}); "
                           "a rig is locked under its address, so it cannot be driven by name "
                           "until the name resolves (or type its address)") from None
    out: set[str] = set()
    for family, _, _, _, sockaddr in infos:
        if family not in (socket.AF_INET, socket.AF_INET6):
            continue
        ip = ipaddress.ip_address(str(sockaddr[0]).split("%", 1)[0])
        if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
            ip = ip.ipv4_mapped
        out.add(LOCAL if _local(ip) else ip.compressed)
    if not out:
        raise RigNameError(f"the rig's host {host!r} has no IPv4 or IPv6 address")
    return tuple(sorted(out))


def _local(ip: ipaddress.IPv4Address | ipaddress.IPv6Address) -> bool:
    """Whether `ip` is this machine: loopback, the unspecified address (which
    connects to it), or an address one of its interfaces holds (bindable)."""
    if ip.is_loopback or ip.is_unspecified:
        return True
    family = socket.AF_INET if ip.version == 4 else socket.AF_INET6
    try:
        with socket.socket(family, socket.SOCK_STREAM) as s:
            s.bind((str(ip), 0))
        return True
    except OSError:
        return False


def rig_devices(host: str, port: int, unit: int) -> tuple[str, ...]:
    """The lock keys of the rig at `host`:`port`, unit `unit` (one per address)."""
    return tuple(f"[{a}]:{port}/{unit}" if ":" in a else f"{a}:{port}/{unit}" for a in rig_addresses(host))


def rig_keys(rig: DaqConfig | IstConfig) -> tuple[str, ...]:
    """The lock keys of the rig a DAQ configuration describes: a serial rig's device
    (links resolved), a Modbus rig's every address (RigNameError if its host does
    not resolve)."""
    from quadtank_tui.daq.ist.config import IstConfig

    if isinstance(rig, IstConfig):
        return (rig.lock_key(),)
    return rig_devices(rig.host, rig.port, rig.device_id)


class RigLock:
    """The locks of every key of one rig (session.lock.DaqLock each), held together:
    the same interface as one DaqLock."""

    def __init__(self, device: str, locks: list[DaqLock]) -> None:
        self.device, self._locks = device, locks

    @classmethod
    def of(cls, rig: DaqConfig | IstConfig, lab: LabConfig, *, session: str | None = None,
           take_over: bool = False) -> RigLock:
        """The lock of the rig a DAQ configuration describes, under its identity
        (rig_keys): DaqLockHeld naming it if a live program drives it."""
        from quadtank_tui.daq.ist.config import IstConfig

        if isinstance(rig, IstConfig):  # a serial rig: one key, its device
            key = rig.lock_key()
            return cls(key, [DaqLock.acquire(key, lab, session=session, take_over=take_over)])
        return cls.acquire(rig.host, rig.port, rig.device_id, lab, session=session, take_over=take_over)

    @classmethod
    def acquire(cls, host: str, port: int, unit: int, lab: LabConfig, *, session: str | None = None,
                take_over: bool = False) -> RigLock:
        """Every key's lock, or none: DaqLockHeld (naming the host as typed and the
        key) if a live program holds one; RigNameError if `host` does not resolve."""
        devices = rig_devices(host, port, unit)
        typed = f"[{host}]:{port}/{unit}" if ":" in host else f"{host}:{port}/{unit}"
        got: list[DaqLock] = []
        try:
            for device in devices:
                got.append(DaqLock.acquire(device, lab, session=session, take_over=take_over))
        except DaqLockHeld as held:
            for lock in got:
                lock.release()
            if held.device != typed:
                raise DaqLockHeld(f"{typed} ({held.device})", held.holder, held.uid, held.pid, held.since,
                                  held.session) from None
            raise
        except BaseException:
            for lock in got:
                lock.release()
            raise
        name = typed if devices == (typed,) else f"{typed} ({', '.join(devices)})"
        return cls(name, got)

    @property
    def pid(self) -> int:
        return self._locks[0].pid

    @property
    def since(self) -> datetime:
        return self._locks[0].since

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(lock.device for lock in self._locks)

    def release(self) -> None:
        for lock in self._locks:
            lock.release()

    def transfer(self, pid: int) -> None:
        """Hand every key's lock to `pid` (DaqLockError if one was taken over)."""
        for lock in self._locks:
            lock.transfer(pid)

    @property
    def held(self) -> bool:
        return self.lost() is None

    @property
    def note(self) -> str | None:
        """The last record found that did not win over ours (DaqLock.note)."""
        return next((lock.note for lock in self._locks if lock.note is not None), None)

    def lost(self) -> str | None:
        """None while every key's lock is ours; else why not (the first one lost)."""
        for lock in self._locks:
            why = lock.lost()
            if why is not None:
                return why
        return None

    def __enter__(self) -> RigLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

    def __repr__(self) -> str:
        return f"RigLock({self.device!r}, pid={self.pid}, since={self.since:%H:%M:%S})"

