"""One program at a time drives a given DAQ: lock records per device in the lab's
runtime folder (`runtime_dir/locks/<address>_<port>_<unit>~<uid>.lock`, one per
user, the host resolved first: session/riglock.py) that name the holder, so the
second program says who to ask instead of fighting over the pumps.

A record is one JSON object: user, uid, pid (and the pid's start time, so a
recycled pid is not taken for the holder), since, session, take_over and a token.
The record, not a flock, says who holds the rig: a lock outlives the launcher and
can be handed to the session process (`transfer`).  A holder that died (SIGKILL, a
crash) leaves a record whose pid is gone: it counts for nothing.

Why nobody can forge, remove or block a record (issue 24):

- The locks folder is sticky (1777, like /tmp) and root's: everyone may create
  entries, nobody but their owner (and root) may remove or rename them.  Each user writes a
  record of their own (`~<uid>` in its name; a name someone else's entry occupies
  gets a random suffix), so a record is never replaced by another user.
- A record counts (is genuine) only if its file's owner is the user it names and
  its pid is a live process of that user.  Anything else - a forged record, a
  directory, a link, junk - is ignored.
- Of the live genuine records, the one written first holds the rig, ranked by the
  file's change time (ctime: set by the kernel on every write, never moved back
  by its owner; a `since` or a pid are written by the student and could name an
  old process).  A later record holds instead only if it is a take-over by an
  administrator (by the reader's lab rules) or by the holder's own user.  Every
  other program sees it lost (`lost`) and stops: two honest programs never drive
  at once, even if one went on without the flock.
- Read-check-write in `acquire` happens under `flock` on the locks folder, so two
  programs starting at once rarely both write.  The flock is waited for at most
  LOCK_WAIT seconds; a program holding it longer (anyone may flock a folder they
  can read: a student holding it blocked every other student) is named (from
  /proc/locks, in `note`) and the program goes on without it: the ranking decides
  all the same, since each program checks, after writing its record, that no
  earlier live record wins over it (and removes its own if one does).  A release
  or transfer waits at most QUICK_WAIT.

Where the records live (issue 41): locks/ of the runtime folder in force
(session/folders.py), which `quadtank lab init` makes root's, 1777 sticky, in a
runtime folder of root's that nobody else may write (1755).  So no student can
make locks/ first (and own it: the owner of a sticky folder may remove every
entry in it), replace it with a link, or remove another's record (the sticky
bit: only the record's owner, the folder's owner and root may); a record's
content counts only as far as the kernel agrees (its file's owner, its pid's real
uid).  That is why a plain folder suffices and no lock service is needed: every
guarantee is the kernel's, and a rig stays lockable with no daemon running.
Without a lab folder each user's locks are in their own folder (/tmp/quadtank-UID):
they keep that user's own programs apart only (`quadtank lab` says so).

The API (what bookings or a front end build on; everything else is private):
`DaqLock.acquire(device, lab, session=, take_over=)` -> a held lock, or
DaqLockHeld naming the holder, NotPermitted for a student's take-over, DaqLockError
for an unusable folder; `lock.lost()` (None while held, else why: polled by
session/lockwatch.py), `lock.note`, `lock.release()`, `lock.transfer(pid)`;
`holder_of(device, lab)` -> who drives it now (DaqLockHeld) or None.  A rig's
several keys (addresses) are held together by session/riglock.RigLock, which has
the same interface; `RigLock.of(rig_config, lab)` is the one entry point programs
use.  A policy that refuses a program before it drives (a booking held by someone
else) belongs before `RigLock.of`, as session/bookings.py does: the lock itself
stays first-come among the programs that policy lets through.

What it cannot prevent: a student may name any live process of their own (a
`sleep`) and so "reserve" a free rig; the message names them and an administrator
may take it over.  The lock is cooperative: it keeps honest programs from
colliding and lets no one end another's run without the lab's say; it is not a
security boundary (the rig's Modbus port is one anyway).
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import re
import secrets
import stat
import time
from dataclasses import dataclass, replace
from datetime import datetime
from pathlib import Path
from typing import Any

from quadtank_tui.files.proc import pid_alive, process_owner, process_start
from quadtank_tui.files.shared import shown
from quadtank_tui.session.lab import LabConfig, ensure_runtime_dir
from quadtank_tui.session.roles import NotPermitted, current_user, is_administrator, user_name
from quadtank_tui.session.runtime import valid_id

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


def _stem(device: str) -> str:
    """`device` as a file name (any character but letters, digits, '.', '-' -> '_')."""
    return re.sub(r"[^A-Za-z0-9.-]", "_", device)


def lock_path(device: str, lab: LabConfig, uid: int | None = None) -> Path:
    """The lock record of `device` for the user `uid` (default: ours)."""
    return lab.locks_dir / f"{_stem(device)}~{os.getuid() if uid is None else uid}.lock"


#: Records of one user for one device looked at (more are junk of that user's own:
#: counted per user, after the owner check, so nobody's junk hides another's record).
MAX_PER_USER = 8


@dataclass(frozen=True)
class _Record:
    user: str
    uid: int
    pid: int
    start: int | None
    since: datetime
    session: str | None
    token: str
    take_over: bool = False

    def to_json(self) -> str:
        return json.dumps({"user": self.user, "uid": self.uid, "pid": self.pid, "start": self.start,
                           "since": self.since.isoformat(timespec="seconds"), "session": self.session,
                           "token": self.token, "take_over": self.take_over}) + "\n"

    @classmethod
    def from_json(cls, text: str) -> _Record | None:
        """The record, or None for an empty or unreadable file (a free lock)."""
        try:
            d: Any = json.loads(text)
            return cls(str(d["user"]), int(d["uid"]), int(d["pid"]),
                       None if d.get("start") is None else int(d["start"]),
                       datetime.fromisoformat(d["since"]), d.get("session"), str(d.get("token", "")),
                       bool(d.get("take_over", False)))
        except (ValueError, KeyError, TypeError, RecursionError, OverflowError):  # Infinity as a uid
            return None

    def held(self, device: str) -> DaqLockHeld:
        return DaqLockHeld(device, self.user, self.uid, self.pid, self.since, self.session)


@dataclass(frozen=True)
class _Found:
    """A live genuine record, its file and the file's change time (the rank)."""

    record: _Record
    path: Path
    ctime_ns: int

    @property
    def rank(self) -> tuple[int, int, str]:
        return (self.ctime_ns, self.record.uid, self.path.name)


def _name_uid(name: str, stem: str) -> int | None:
    """The uid a record's file name says it is of (`<stem>~<uid>[.<x>].lock`)."""
    if not name.startswith(stem + "~") or not name.endswith(".lock"):
        return None
    digits = name[len(stem) + 1:-len(".lock")].split(".", 1)[0]
    return int(digits) if digits.isdigit() and len(digits) < 11 else None


def _read(path: Path, uid: int) -> tuple[_Record, int] | None:
    """The record at `path` and its ctime if the file is a regular file of `uid`
    naming `uid` (no symbolic link followed), else None."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_uid != uid:
            return None
        rec = _Record.from_json(os.read(fd, MAX_RECORD).decode("utf-8", "replace"))
        if rec is None or rec.uid != uid:
            return None
        # What is shown of it (in a refusal on another user's terminal) carries no
        # control character: the name escaped, the session only if it is a session id.
        session = rec.session if isinstance(rec.session, str) and valid_id(rec.session) else None
        return replace(rec, user=shown(rec.user), session=session), st.st_ctime_ns
    except OSError:
        return None
    finally:
        os.close(fd)


def _genuine(rec: _Record) -> bool:
    """Whether the record's process runs, as the user the record names."""
    runs_as = process_owner(rec.pid)
    return (runs_as is None or runs_as == rec.uid) and pid_alive(rec.pid, rec.start)


def _records(device: str, lab: LabConfig) -> list[_Found]:
    """The live genuine records of `device`, earliest written first."""
    stem = _stem(device)
    out: list[_Found] = []
    try:
        entries = os.scandir(lab.locks_dir)
    except OSError:
        return out
    seen: dict[int, int] = {}
    with entries:
        for entry in entries:
            uid = _name_uid(entry.name, stem)
            if uid is None:
                continue
            try:
                st = entry.stat(follow_symlinks=False)
            except OSError:
                continue
            if not stat.S_ISREG(st.st_mode) or st.st_uid != uid:
                continue  # forged, a directory, a link: never a record
            seen[uid] = seen.get(uid, 0) + 1
            if seen[uid] > MAX_PER_USER:
                continue
            got = _read(Path(entry.path), uid)
            if got is not None and _genuine(got[0]):
                out.append(_Found(got[0], Path(entry.path), got[1]))
    return sorted(out, key=lambda f: f.rank)


def _winner(found: list[_Found], lab: LabConfig) -> _Found | None:
    """Who holds the rig: the earliest record, unless a later one is a take-over
    by an administrator or by the holder's own user."""
    if not found:
        return None
    win = found[0]
    for f in found[1:]:
        if f.record.take_over and (f.record.uid == win.record.uid or is_administrator(f.record.uid, lab)):
            win = f
    return win


def _put(path: Path, rec: _Record) -> None:
    """Make `rec` our record at `path`: written as a new file of ours (0644) and
    renamed over the old one, so a reader sees the old record or the new one."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    except OSError as exc:
        raise DaqLockError(f"{path.parent}: cannot write a lock record there ({exc.strerror}); "
                           "an administrator may fix the folder's permissions") from None
    try:
        try:
            os.fchmod(fd, 0o644)  # whatever the umask: everyone reads who holds the rig
            os.write(fd, rec.to_json().encode())
            os.fsync(fd)
        finally:
            os.close(fd)
        os.rename(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise DaqLockError(f"{path}: cannot write the lock record ({exc.strerror})") from None


def _own_path(device: str, lab: LabConfig) -> Path:
    """Where this user's record of `device` goes: `<stem>~<uid>.lock`, or, if
    someone else's entry (a directory, a file of another user) sits there, a name
    of ours with a random suffix."""
    path = lock_path(device, lab)
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return path
    except OSError:
        st = None
    if st is not None and stat.S_ISREG(st.st_mode) and st.st_uid == os.getuid():
        return path
    uid = os.getuid()
    for entry in _own_entries(device, lab):
        if entry != path:
            return entry  # an earlier one of ours with a suffix
    return path.with_name(f"{_stem(device)}~{uid}.{secrets.token_hex(4)}.lock")


def _own_entries(device: str, lab: LabConfig) -> list[Path]:
    """Our regular files among `device`'s records (stale ones included)."""
    stem, uid = _stem(device), os.getuid()
    out = []
    with contextlib.suppress(OSError), os.scandir(lab.locks_dir) as entries:
        for entry in entries:
            if _name_uid(entry.name, stem) == uid:
                with contextlib.suppress(OSError):
                    st = entry.stat(follow_symlinks=False)
                    if stat.S_ISREG(st.st_mode) and st.st_uid == uid:
                        out.append(Path(entry.path))
    return sorted(out)


# --- the flock on the locks folder: serializes read-check-write, never waits for long ------

def _open_folder(folder: Path) -> int:
    try:
        return os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError as exc:
        raise DaqLockError(f"{folder}: the lock folder cannot be opened ({exc.strerror})") from None


def flock_within(fd: int, wait: float) -> bool:
    """An exclusive flock on `fd` within `wait` seconds (whether it was had): a
    shared folder's flock anyone who may read it may take, and hold for ever."""
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
        #: another program's record found and not yielded to (a student's take-over,
        #: a later start), for the program to say; None: nothing
        self.note: str | None = None

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
        `transfer`) is adopted."""
        ensure_runtime_dir(lab)
        me = current_user()
        folder = _open_folder(lab.locks_dir)
        busy: str | None = None
        try:
            if not flock_within(folder, LOCK_WAIT):  # someone holds it: go on without it (the ranking decides)
                busy = _busy(lab.locks_dir, folder, LOCK_WAIT) + "; this program went on without it"
            found = _records(device, lab)
            mine = next((f for f in found if f.record.pid == me.pid and f.record.uid == me.uid), None)
            others = [f for f in found if f is not mine]
            old = _winner(others, lab)
            if old is not None:
                if not take_over:
                    raise old.record.held(device)
                for f in others:
                    if f.record.uid != me.uid and not is_administrator(me.uid, lab):
                        raise NotPermitted(f"taking over the rig at {device} from {f.record.user} needs an "
                                           f"administrator; you are {me.user}")
            since = mine.record.since if mine is not None else datetime.now().astimezone().replace(microsecond=0)
            rec = _Record(me.user, me.uid, me.pid, process_start(me.pid), since, session, secrets.token_hex(8),
                          take_over=old is not None or (mine is not None and mine.record.take_over))
            path = _own_path(device, lab)
            _put(path, rec)
            for stale in _own_entries(device, lab):
                if stale != path:  # ours, of programs gone or taken over by this one
                    with contextlib.suppress(OSError):
                        os.unlink(stale)
            lock = cls(device, path, rec, lab)
            lock.note = busy
            won = _winner(_records(device, lab), lab)
            if won is not None and not lock._ours(won):  # one went on without the flock, and was first
                lock._remove()
                raise won.record.held(device)
        finally:
            os.close(folder)  # closing drops the flock
        return lock

    def _ours(self, found: _Found) -> bool:
        return found.record.token == self._record.token and found.path == self.path

    def _remove(self) -> None:
        got = _read(self.path, os.getuid())
        if got is not None and got[0].token == self._record.token:
            with contextlib.suppress(OSError):
                os.unlink(self.path)

    def release(self) -> None:
        """Free the device (idempotent; a lock taken over by our own user or
        transferred is left to its new holder): our record is removed."""
        if self._released:
            return
        self._released = True
        try:
            folder = _open_folder(self.path.parent)
        except DaqLockError:
            return  # the folder went wrong: the record names a process that is ending
        try:
            flock_within(folder, QUICK_WAIT)  # had or not: a stopping program does not wait longer
            self._remove()
        finally:
            os.close(folder)

    def transfer(self, pid: int) -> None:
        """Hand the lock to `pid` (the session process this launcher started): the
        record names it from now on, and this object's release does nothing."""
        rec = self._record
        new = _Record(rec.user, rec.uid, pid, process_start(pid), rec.since, rec.session, rec.token, rec.take_over)
        folder = _open_folder(self.path.parent)
        try:
            flock_within(folder, QUICK_WAIT)
            got = _read(self.path, os.getuid())
            if got is None or got[0].token != rec.token:
                raise DaqLockError(f"{self.path}: the lock of {self.device} is no longer ours (taken over)")
            _put(self.path, new)
        finally:
            os.close(folder)
        self._record = new
        self._released = True

    @property
    def held(self) -> bool:
        """Whether this program still holds the lock (an administrator may have taken it over)."""
        return self.lost() is None

    def lost(self) -> str | None:
        """None while this program holds the lock; else why not, for the user (who
        took it over, or drove it first).  A later record that does not win (a
        student's take-over, a program that went on without the flock) is told in
        `note`; that program stops by itself.  A released or transferred lock is
        not ours either."""
        if self._released:
            return "the lock was released"
        found = _records(self.device, self._lab)
        mine = next((f for f in found if self._ours(f)), None)
        if mine is None:
            got = _read(self.path, os.getuid())
            if got is not None and _genuine(got[0]):  # our own user's take-over
                return (f"the rig at {self.device} was taken over by {got[0].user} (pid {got[0].pid}) "
                        f"at {datetime.now():%H:%M:%S}")
            return f"the lock record of the rig at {self.device} ({self.path}) was removed"
        win = _winner(found, self._lab)
        assert win is not None
        if win is not mine:
            w = win.record
            if win.rank > mine.rank:
                return f"the rig at {self.device} was taken over by {w.user} (pid {w.pid}) at {datetime.now():%H:%M:%S}"
            return f"{w.held(self.device)}, and that program started first"
        later = [f.record for f in found if f is not mine]
        if later:
            r = later[-1]
            self.note = (f"{r.user} (not an administrator) tried to take the rig at {self.device} over; refused"
                         if r.take_over else
                         f"{r.user} (pid {r.pid}) started on the rig at {self.device} after this program; "
                         "it must stop")
        return None

    def __enter__(self) -> DaqLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

    def __repr__(self) -> str:
        return f"DaqLock({self.device!r}, pid={self.pid}, since={self.since:%H:%M:%S})"


def holder_of(device: str, lab: LabConfig) -> DaqLockHeld | None:
    """Who drives `device` now (None: nobody; dead holders' and forged records count for nothing)."""
    win = _winner(_records(device, lab), lab)
    return win.record.held(device) if win is not None else None
