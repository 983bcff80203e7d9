"""One program at a time drives a given DAQ: a lock record per device in the lab's
runtime folder (`runtime_dir/locks/<address>_<port>_<unit>.lock`, the host resolved
first: session/riglock.py) that names its holder, so the second program says who
to ask instead of fighting over the pumps.

The record is one JSON object: user, uid, pid (and the pid's start time, so a
recycled pid is not taken for the holder), since, session, and a token.  The
record, not a flock, says who holds the rig: a lock outlives the launcher and can be
handed to the session process (`transfer`).  A holder that died (SIGKILL, a crash)
leaves a record whose pid is gone: the next program takes it over silently.

Why a record no one can forge (issue 24: lock files were 0666, and anyone could
write `user teacher, pid 1` and lock everyone out, root included):

- A record is written by its holder as a file of its own (0644, created under a
  random name, then renamed over the lock's name), so the file's owner is its
  writer.  A record whose owner (file uid) differs from the user it names, or whose
  pid belongs to another user, is forged and counts as free; so does one that
  cannot be read or parsed.  Nobody writes into another's file.
- The locks folder is writable by every lab user and not sticky (renaming over
  another's stale record must work); so anyone may replace or remove a record.
  That is why the holder decides whether it lost the rig (`lost`): only a genuine
  live record of an administrator - by the holder's own lab rules, never the
  taker's - or of the holder's own user takes it over; anything else (a student's
  record, a forged or removed one) is replaced by the holder's record again.
- Read-check-write in `acquire` happens under `flock` on the locks folder, so two
  programs starting at once cannot both win.  The flock is waited for at most
  LOCK_WAIT seconds and a program holding it longer is named (from /proc/locks);
  an administrator then goes on without it (the rename is atomic), anyone else is
  refused with that name.  A release or transfer waits at most QUICK_WAIT and never
  blocks a stopping program.

The lock is cooperative: it keeps honest programs from colliding and lets no one
end another's run without the lab's say; it is not a security boundary (the rig's
Modbus port is one anyway).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import re
import secrets
import stat
import time
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from quadtank_tui.session.lab import LabConfig, ensure_runtime_dir
from quadtank_tui.session.roles import NotPermitted, current_user, is_administrator, user_name

#: A lock record is a few hundred bytes.
MAX_RECORD = 4096
#: Seconds `acquire` waits for the locks folder's flock (held for milliseconds by
#: an honest program) before it names whoever holds it.
LOCK_WAIT = 3.0
#: Seconds a release, a transfer or a look at the record waits for it.
QUICK_WAIT = 1.0


class DaqLockError(OSError):
    """The lock cannot be used (its folder not writable, ...)."""


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
        except (ValueError, KeyError, TypeError, RecursionError):
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


def process_owner(pid: int) -> int | None:
    """The user id `pid` runs as (/proc), None where unknown."""
    try:
        return os.stat(f"/proc/{pid}").st_uid
    except OSError:
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


@dataclass(frozen=True)
class _Found:
    """What the lock file holds now: its record (None: none, unreadable or not
    JSON) and the file's owner (None: no file, or not a regular one)."""

    record: _Record | None
    owner: int | None

    @property
    def genuine(self) -> bool:
        """Written by the user it names, about a process of that user."""
        rec = self.record
        if rec is None or self.owner is None or self.owner != rec.uid:
            return False
        runs_as = process_owner(rec.pid)
        return runs_as is None or runs_as == rec.uid

    @property
    def live(self) -> _Record | None:
        """The record if it is genuine and its process runs (the holder), else None."""
        rec = self.record
        return rec if rec is not None and self.genuine and pid_alive(rec.pid, rec.start) else None


def _look(path: Path) -> _Found:
    """The record at `path` and its file's owner (no symbolic link followed)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError:  # none, a link, or not readable for us: no record
        return _Found(None, None)
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            return _Found(None, None)
        return _Found(_Record.from_json(os.read(fd, MAX_RECORD).decode("utf-8", "replace")), st.st_uid)
    except OSError:
        return _Found(None, None)
    finally:
        os.close(fd)


def _put(path: Path, rec: _Record | None) -> None:
    """Make `rec` (None: an empty, free record) the lock file at `path`: written as a
    new file of ours (0644) and renamed over the old one, so its owner is its writer
    and a reader sees the old record or the new one, never half of one."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    except OSError as exc:
        raise DaqLockError(f"{path.parent}: cannot write a lock record there ({exc.strerror}); "
                           "an administrator may fix the folder's permissions") from None
    try:
        try:
            os.fchmod(fd, 0o644)  # whatever the umask: everyone reads who holds the rig
            if rec is not None:
                os.write(fd, rec.to_json().encode())
            os.fsync(fd)
        finally:
            os.close(fd)
        os.rename(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if exc.errno in (errno.EPERM, errno.EACCES, errno.EISDIR, errno.ENOTEMPTY, errno.EEXIST):
            owner = _owner_name(path)
            raise DaqLockError(f"{path}: the lock file (of {owner}) cannot be replaced by you "
                               f"({exc.strerror}); an administrator may remove it") from None
        raise


def _owner_name(path: Path) -> str:
    try:
        return user_name(os.lstat(path).st_uid)
    except OSError:
        return "nobody"


# --- the flock on the locks folder: serializes read-check-write, never waits for long ------

def _open_folder(folder: Path) -> int:
    try:
        return os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError as exc:
        raise DaqLockError(f"{folder}: the lock folder cannot be opened ({exc.strerror})") from None


def _flock(fd: int, wait: float) -> bool:
    """An exclusive flock on `fd` within `wait` seconds (whether it was had)."""
    deadline = time.monotonic() + wait
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return True
        except BlockingIOError:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.02)


def flock_holders(fd: int) -> list[tuple[int, str]]:
    """(pid, user) of the processes holding a flock on the file `fd` is open on,
    from /proc/locks (the kernel's, not a record anyone wrote)."""
    ino = os.fstat(fd).st_ino
    out: list[tuple[int, str]] = []
    try:
        with open("/proc/locks") as f:
            lines = f.readlines()
    except OSError:
        return out
    for line in lines:
        fields = line.split()
        if "->" in fields:  # a waiter, not a holder
            continue
        try:
            kind, pid, where = fields[1], int(fields[4]), fields[5]
        except (IndexError, ValueError):
            continue
        if kind == "FLOCK" and where.rsplit(":", 1)[-1] == str(ino):
            uid = process_owner(pid)
            out.append((pid, user_name(uid) if uid is not None else "someone"))
    return out


def _busy(folder: Path, fd: int, wait: float) -> str:
    holders = flock_holders(fd)
    who = ", ".join(f"{user} (pid {pid})" for pid, user in holders) or "another program"
    return f"{folder}: the lock folder has been held by {who} for more than {wait:g} s"


class DaqLock:
    """The right to drive one DAQ device; see the module docstring."""

    def __init__(self, device: str, path: Path, record: _Record, lab: LabConfig) -> None:
        self.device, self.path, self._record, self._lab = device, path, record, lab
        self._released = False
        #: what the holder found instead of its record and replaced (a forged record,
        #: a student's take-over, a removal), for the program to say; None: nothing
        self.restored: str | None = None

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
        holds it (unless `take_over`, for an administrator or the holder's own user:
        NotPermitted otherwise).  A lock held by this very pid (handed over by
        `transfer`) is adopted.  A forged, unreadable or dead holder's record is
        replaced."""
        ensure_runtime_dir(lab)
        path = lock_path(device, lab)
        me = current_user()
        folder = _open_folder(lab.locks_dir)
        try:
            if not _flock(folder, LOCK_WAIT) and not is_administrator(me.uid, lab):
                raise DaqLockError(_busy(lab.locks_dir, folder, LOCK_WAIT)
                                   + "; an administrator may go on without it")
            old = _look(path).live
            if old is not None and old.pid != me.pid:
                if not take_over:
                    raise old.held(device)
                if old.uid != me.uid and not is_administrator(me.uid, lab):
                    raise NotPermitted(f"taking over the rig at {device} from {old.user} needs an "
                                       f"administrator; you are {me.user}")
            since = old.since if old is not None and old.pid == me.pid else \
                datetime.now().astimezone().replace(microsecond=0)
            rec = _Record(me.user, me.uid, me.pid, process_start(me.pid), since, session, secrets.token_hex(8))
            _put(path, rec)
        finally:
            os.close(folder)  # closing drops the flock
        return cls(device, path, rec, lab)

    def _ours(self, found: _Found) -> bool:
        rec = found.record
        return rec is not None and rec.token == self._record.token and found.owner == os.getuid()

    def _update(self, new: _Record | None) -> bool:
        """Replace our record by `new` if the file still holds ours (a take-over may
        have replaced it); whether it did."""
        try:
            folder = _open_folder(self.path.parent)
        except DaqLockError:
            return False
        try:
            _flock(folder, QUICK_WAIT)  # had or not: a stopping program does not wait longer
            if not self._ours(_look(self.path)):
                return False
            _put(self.path, new)
            return True
        finally:
            os.close(folder)

    def release(self) -> None:
        """Free the device (idempotent; a lock taken over or transferred is left
        to its new holder).  The file stays, empty and ours."""
        if self._released:
            return
        self._released = True
        try:
            self._update(None)
        except DaqLockError:
            pass  # the folder went wrong: the record names a process that is ending

    def transfer(self, pid: int) -> None:
        """Hand the lock to `pid` (the session process this launcher started): the
        record names it from now on, and this object's release does nothing."""
        rec = self._record
        new = _Record(rec.user, rec.uid, pid, process_start(pid), rec.since, rec.session, rec.token)
        if not self._update(new):
            raise DaqLockError(f"{self.path}: the lock of {self.device} is no longer ours (taken over)")
        self._record = new
        self._released = True

    @property
    def held(self) -> bool:
        """Whether this program still holds the lock (an administrator may have taken it over)."""
        return self.lost() is None

    def lost(self) -> str | None:
        """None while this program holds the lock; else why not, for the user (who
        took it over and when).  Only a genuine live record of an administrator (by
        this holder's lab rules) or of our own user takes the lock; a forged, a
        removed or a student's record is replaced by ours again (`restored` says
        what was found).  A released or transferred lock is not ours either."""
        if self._released:
            return "the lock was released"
        found = _look(self.path)
        if self._ours(found):
            return None
        taker = found.live
        if taker is not None and (taker.uid == self._record.uid or is_administrator(taker.uid, self._lab)):
            return (f"the rig at {self.device} was taken over by {taker.user} (pid {taker.pid}) "
                    f"at {datetime.now():%H:%M:%S}")
        self.restored = _describe(found, self.device)
        _put(self.path, self._record)
        return None

    def __enter__(self) -> DaqLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

    def __repr__(self) -> str:
        return f"DaqLock({self.device!r}, pid={self.pid}, since={self.since:%H:%M:%S})"


def _describe(found: _Found, device: str) -> str:
    """What replaced a holder's record, for its user."""
    rec = found.record
    if rec is None:
        return f"the lock of the rig at {device} was removed or made unreadable; put back"
    writer = user_name(found.owner) if found.owner is not None else "someone"
    if not found.genuine:
        return f"a forged lock record (naming {rec.user}, written by {writer}) was replaced"
    return f"{writer} (not an administrator) tried to take the rig at {device} over; refused"


def holder_of(device: str, lab: LabConfig) -> DaqLockHeld | None:
    """Who drives `device` now (None: nobody, a dead holder's or a forged record)."""
    rec = _look(lock_path(device, lab)).live
    return rec.held(device) if rec is not None else None
