"""One program at a time drives a given DAQ: a lock file per device in the lab's
runtime folder (`runtime_dir/locks/<address>_<port>_<unit>.lock`, the host resolved
first: session/riglock.py) that names its holder, so the second program says who
to ask instead of fighting over the pumps.

The file holds one JSON record: user, uid, pid (and the pid's start time, so a
recycled pid is not taken for the holder), since, session, and a token.  Every
read-check-write happens under `flock` on the file, so two programs starting at
once cannot both win.  The record, not the flock, says who holds the rig: a lock
outlives the launcher's flock and can be handed to the session process
(`transfer`).  A holder that died (SIGKILL, a crash) leaves a record whose pid is
gone: the next program takes it over silently.

Permissions: the locks folder is 1777 like /tmp (nobody removes another's file)
and a lock file is 0666, so every lab user reads who holds a rig and may take over
a stale lock.  The lock is cooperative: it keeps honest programs from colliding,
it is not a security boundary (the rig's Modbus port is one anyway).
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import re
import secrets
import stat
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from quadtank_tui.session.lab import LabConfig, ensure_runtime_dir
from quadtank_tui.session.roles import current_user, user_name

#: A lock record is a few hundred bytes.
MAX_RECORD = 4096


class DaqLockError(OSError):
    """The lock file cannot be used (not a regular file, not writable, ...)."""


class DaqLockHeld(RuntimeError):
    """Another live program drives the device."""

    def __init__(self, device: str, holder: str, uid: int, pid: int, since: datetime,
                 session: str | None = None) -> None:
        self.device, self.holder, self.uid, self.pid = device, holder, uid, pid
        self.since, self.session = since, session
        super().__init__(self.text())

    def __reduce__(self) -> tuple[Any, ...]:  # sent between processes intact
        return (type(self), (self.device, self.holder, self.uid, self.pid, self.since, self.session))

    def text(self, now: datetime | None = None) -> str:
        now = now or datetime.now(self.since.tzinfo)
        when = self.since.strftime("%H:%M" if self.since.date() == now.date() else "%Y-%m-%d %H:%M")
        session = f", session {self.session}" if self.session else ""
        return f"the rig at {self.device} is driven by {self.holder} (pid {self.pid}{session}) since {when}"


def device_key(host: str, port: int, unit: int) -> str:
    """The name a DAQ is locked under: its Modbus TCP address and unit id."""
    return f"{host}:{port}/{unit}"


def lock_path(device: str, lab: LabConfig) -> Path:
    """The lock file of `device` (any character but letters, digits, '.', '-' -> '_')."""
    return lab.locks_dir / (re.sub(r"[^A-Za-z0-9.-]", "_", device) + ".lock")


@dataclass(frozen=True)
class _Record:
    user: str
    uid: int
    pid: int
    start: int | None
    since: datetime
    session: str | None
    token: str

    def to_json(self) -> str:
        return json.dumps({"user": self.user, "uid": self.uid, "pid": self.pid, "start": self.start,
                           "since": self.since.isoformat(timespec="seconds"), "session": self.session,
                           "token": self.token}) + "\n"

    @classmethod
    def from_json(cls, text: str) -> _Record | None:
        """The record, or None for an empty or unreadable file (a free lock)."""
        try:
            d: Any = json.loads(text)
            return cls(str(d["user"]), int(d["uid"]), int(d["pid"]),
                       None if d.get("start") is None else int(d["start"]),
                       datetime.fromisoformat(d["since"]), d.get("session"), str(d.get("token", "")))
        except (ValueError, KeyError, TypeError):
            return None

    def held(self, device: str) -> DaqLockHeld:
        return DaqLockHeld(device, self.user, self.uid, self.pid, self.since, self.session)


def _proc_stat(pid: int) -> list[bytes] | None:
    """The fields of /proc/<pid>/stat after the command name (state first), None
    where there is no such file."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            data = f.read()
        return data[data.rindex(b")") + 2:].split()
    except (OSError, ValueError):
        return None


def process_start(pid: int) -> int | None:
    """The start time of `pid` in clock ticks since boot (/proc), None where unknown."""
    fields = _proc_stat(pid)
    try:
        return None if fields is None else int(fields[19])
    except (ValueError, IndexError):
        return None


def pid_alive(pid: int, start: int | None = None) -> bool:
    """Whether `pid` runs (another user's process counts) and, given its recorded
    start time, is still the same process and not a recycled pid."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    fields = _proc_stat(pid)
    if fields is None:
        return True  # no /proc: the kill probe has the last word
    if fields[:1] == [b"Z"]:
        return False  # exited, not yet reaped by its parent: it holds nothing
    if start is not None:
        now = process_start(pid)
        return now is None or now == start
    return True


def _alive(rec: _Record) -> bool:
    return pid_alive(rec.pid, rec.start)


def _open(path: Path, *, create: bool) -> int:
    """The lock file's descriptor (no symlinks followed, regular files only)."""
    flags = os.O_RDWR | os.O_NOFOLLOW | os.O_CLOEXEC | (os.O_CREAT if create else 0)
    try:
        fd = os.open(path, flags, 0o666)
    except PermissionError:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise DaqLockError(f"{path}: the lock file is a symbolic link; remove it") from None
        raise
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        raise DaqLockError(f"{path}: the lock file is not a regular file; remove it")
    if st.st_uid == os.getuid() and stat.S_IMODE(st.st_mode) != 0o666:
        os.fchmod(fd, 0o666)  # the umask took bits off: others must read and take over
    return fd


def _read(fd: int) -> _Record | None:
    os.lseek(fd, 0, os.SEEK_SET)
    return _Record.from_json(os.read(fd, MAX_RECORD).decode("utf-8", "replace"))


def _write(fd: int, path: Path, rec: _Record | None) -> None:
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        os.ftruncate(fd, 0)
        if rec is not None:
            os.write(fd, rec.to_json().encode())
        os.fsync(fd)
    except OSError as exc:
        if exc.errno in (errno.EBADF, errno.EINVAL, errno.EACCES, errno.EPERM):
            owner = user_name(os.fstat(fd).st_uid)
            raise DaqLockError(f"{path}: the lock file (of {owner}) is not writable for you; "
                               "an administrator may remove it") from None
        raise


class DaqLock:
    """The right to drive one DAQ device; see the module docstring."""

    def __init__(self, device: str, path: Path, record: _Record) -> None:
        self.device, self.path, self._record = device, path, record
        self._released = False

    @property
    def pid(self) -> int:
        return self._record.pid

    @property
    def since(self) -> datetime:
        return self._record.since

    @classmethod
    def acquire(cls, device: str, lab: LabConfig, *, session: str | None = None,
                take_over: bool = False) -> DaqLock:
        """The lock of `device` for this process; DaqLockHeld if a live program
        holds it (unless `take_over`: the caller checked require_administrator).
        A lock held by this very pid (handed over by `transfer`) is adopted."""
        ensure_runtime_dir(lab)
        path = lock_path(device, lab)
        me = current_user()
        fd = _open(path, create=True)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            old = _read(fd)
            if old is not None and old.pid != me.pid and _alive(old) and not take_over:
                raise old.held(device)
            since = old.since if old is not None and old.pid == me.pid else datetime.now().astimezone().replace(microsecond=0)
            rec = _Record(me.user, me.uid, me.pid, process_start(me.pid), since, session, secrets.token_hex(8))
            _write(fd, path, rec)
        finally:
            os.close(fd)  # closing drops the flock
        return cls(device, path, rec)

    def _update(self, new: _Record | None) -> bool:
        """Replace our record by `new` if the file still holds ours (a takeover may
        have replaced it); whether it did."""
        try:
            fd = _open(self.path, create=False)
        except FileNotFoundError:
            return False
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            current = _read(fd)
            if current is None or current.token != self._record.token:
                return False
            _write(fd, self.path, new)
            return True
        finally:
            os.close(fd)

    def release(self) -> None:
        """Free the device (idempotent; a lock taken over or transferred is left
        to its new holder).  The file stays, empty: removing it would race with a
        program that has it open."""
        if self._released:
            return
        self._released = True
        self._update(None)

    def transfer(self, pid: int) -> None:
        """Hand the lock to `pid` (the session process this launcher started): the
        record names it from now on, and this object's release does nothing."""
        rec = self._record
        new = _Record(rec.user, rec.uid, pid, process_start(pid), rec.since, rec.session, rec.token)
        if not self._update(new):
            raise DaqLockError(f"{self.path}: the lock of {self.device} is no longer ours (taken over)")
        self._record = new
        self._released = True

    def _current(self) -> _Record | None:
        """The record in the file now (under a shared flock: a writer truncates, then
        writes, and an unlocked reader could see the empty file in between)."""
        try:
            fd = _open(self.path, create=False)
        except FileNotFoundError:
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH)
            return _read(fd)
        finally:
            os.close(fd)

    @property
    def held(self) -> bool:
        """Whether the file still names this lock (an administrator may have taken it over)."""
        return self.lost() is None

    def lost(self) -> str | None:
        """None while the file names this lock; else why not, for the user (who took
        it over and when).  A released or transferred lock is not ours either."""
        if self._released:
            return "the lock was released"
        current = self._current()
        if current is not None and current.token == self._record.token:
            return None
        if current is None:
            return f"the lock of the rig at {self.device} was removed"
        return (f"the rig at {self.device} was taken over by {current.user} (pid {current.pid}) "
                f"at {datetime.now():%H:%M:%S}")

    def __enter__(self) -> DaqLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

    def __repr__(self) -> str:
        return f"DaqLock({self.device!r}, pid={self.pid}, since={self.since:%H:%M:%S})"


def holder_of(device: str, lab: LabConfig) -> DaqLockHeld | None:
    """Who drives `device` now (None: nobody, or only a dead holder's record)."""
    path = lock_path(device, lab)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        fcntl.flock(fd, fcntl.LOCK_SH)
        rec = _read(fd)
    finally:
        os.close(fd)
    return rec.held(device) if rec is not None and _alive(rec) else None
