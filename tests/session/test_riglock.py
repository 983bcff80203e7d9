"""One rig, one lock: the host of a DAQ configuration is resolved before locking, so
`localhost`, `127.0.0.1`, `::1`, `127.0.1.1` and this machine's name are one rig,
a name with several addresses is locked under each, and a name that does not
resolve is refused instead of locked under as typed."""

from __future__ import annotations

import os
import socket
from pathlib import Path

import pytest

from quadtank_tui.session.lab import LabConfig
from quadtank_tui.session.lock import DaqLock, DaqLockHeld, holder_of
from quadtank_tui.session.riglock import LOCAL, RigLock, RigNameError, rig_addresses, rig_devices


@pytest.fixture
def lab(tmp_path: Path) -> LabConfig:
    return LabConfig(runtime_dir=tmp_path / "runtime")


@pytest.mark.parametrize("host", ["localhost", "LOCALHOST", "127.0.0.1", "::1", "127.0.1.1", " localhost ",
                                  "0.0.0.0", "::ffff:127.0.0.1", socket.gethostname()])
def test_every_name_of_this_machine_is_one_key(host: str) -> None:
    assert rig_addresses(host) == (LOCAL,)
    assert rig_devices(host, 5020, 1) == ("127.0.0.1:5020/1",)


def test_other_addresses_are_canonical() -> None:
    assert rig_addresses("192.0.2.7") == ("192.0.2.7",)
    assert rig_addresses("::ffff:192.0.2.7") == ("192.0.2.7",)  # IPv4-mapped: the IPv4 address
    assert rig_addresses("2001:DB8:0:0::5") == ("2001:db8::5",)
    assert rig_devices("2001:db8::5", 502, 3) == ("[2001:db8::5]:502/3",)


def fake_dns(monkeypatch: pytest.MonkeyPatch, names: dict[str, list[str]]) -> None:
    """getaddrinfo answering `names` (a name -> its addresses) and literal addresses."""
    real = socket.getaddrinfo

    def answer(host: str, port: object, *args: object, **kw: object) -> list[tuple]:
        if host in names:
            return [(socket.AF_INET6 if ":" in a else socket.AF_INET, socket.SOCK_STREAM, 6, "", (a, 0))
                    for a in names[host]]
        return real(host, port, *args, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(socket, "getaddrinfo", answer)


def test_a_name_with_two_addresses_collides_with_either(lab: LabConfig, monkeypatch: pytest.MonkeyPatch) -> None:
    fake_dns(monkeypatch, {"rig7.lab.example": ["192.0.2.7", "2001:db8::7", "192.0.2.7"]})
    assert rig_devices("RIG7.lab.example", 502, 1) == ("192.0.2.7:502/1", "[2001:db8::7]:502/1")
    with RigLock.acquire("rig7.lab.example", 502, 1, lab) as lock:
        assert lock.keys == ("192.0.2.7:502/1", "[2001:db8::7]:502/1")
        assert lock.device == "rig7.lab.example:502/1 (192.0.2.7:502/1, [2001:db8::7]:502/1)"
        assert all(holder_of(key, lab) is not None for key in lock.keys)
    # The same pid adopts its own lock (the session after `transfer`), so another
    # holder is a record naming another live pid: our parent.
    # a program holding only the IPv6 address keeps the name out, and nothing is left held
    other = DaqLock.acquire("[2001:db8::7]:502/1", lab)
    try:
        _as_other_pid(lab, "[2001:db8::7]:502/1")
        with pytest.raises(DaqLockHeld) as refused:
            RigLock.acquire("rig7.lab.example", 502, 1, lab)
        assert refused.value.device == "rig7.lab.example:502/1 ([2001:db8::7]:502/1)"
        assert holder_of("192.0.2.7:502/1", lab) is None  # the IPv4 key taken first was given back
    finally:
        other.release()


def _as_other_pid(lab: LabConfig, device: str) -> None:
    """Rewrite `device`'s record to name our parent (alive, not us) as the holder."""
    import json

    from quadtank_tui.session.lock import lock_path, process_start

    path = lock_path(device, lab)
    rec = json.loads(path.read_text())
    rec["pid"], rec["start"] = os.getppid(), process_start(os.getppid())
    path.write_text(json.dumps(rec))


def test_the_loopback_family_is_one_lock(lab: LabConfig) -> None:
    lock = RigLock.acquire("localhost", 5020, 1, lab)
    try:
        _as_other_pid(lab, "127.0.0.1:5020/1")
        for host in ("127.0.0.1", "::1", "LOCALHOST", "127.0.1.1"):
            with pytest.raises(DaqLockHeld) as refused:
                RigLock.acquire(host, 5020, 1, lab)
            typed = f"[{host}]:5020/1" if ":" in host else f"{host}:5020/1"
            assert refused.value.device == (typed if host == "127.0.0.1" else f"{typed} (127.0.0.1:5020/1)")
            assert refused.value.pid == os.getppid()
        with RigLock.acquire("::1", 5021, 1, lab) as another:  # another port: another rig
            assert another.keys == ("127.0.0.1:5021/1",)
    finally:
        lock.release()


def test_a_name_that_does_not_resolve_is_refused(lab: LabConfig) -> None:
    with pytest.raises(RigNameError, match=r"^the rig's host 'no-such-rig\.invalid' does not resolve \("):
        RigLock.acquire("no-such-rig.invalid", 502, 1, lab)
    assert not lab.locks_dir.exists() or not any(lab.locks_dir.iterdir())  # nothing locked under the name
