"""The DAQ lock cannot be forged or held hostage (issue 24): a record whose file
owner differs from the user it names is forged and counts as free; a student's
take-over is refused by the holder, which drives on; a flock held by
someone else is waited for a bounded time and its holder named.

Other users are real uids (root chowns files to them and starts processes as them
with setpriv); the tests are skipped unless run as root, as CI does."""

from __future__ import annotations

import fcntl
import json
import os
import subprocess
import threading
import time
from pathlib import Path
from typing import Iterator

import pytest

from quadtank_tui.session import lock as lockmod
from quadtank_tui.session.lab import LabConfig
from quadtank_tui.session.lock import DaqLock, device_key, holder_of, lock_path, process_start

DEVICE = device_key("192.0.2.7", 502, 1)
STUDENT = 54000 + os.getpid() % 1000   # no such user needs to exist: a uid is enough
TEACHER = STUDENT + 1

root_only = pytest.mark.skipif(os.getuid() != 0, reason="needs root (chown, setpriv)")


@pytest.fixture
def lab(tmp_path: Path) -> LabConfig:
    return LabConfig(runtime_dir=tmp_path / "rt")


@pytest.fixture
def student_process() -> Iterator[subprocess.Popen[bytes]]:
    """A process running as STUDENT (a non-administrator: the installation's
    params/ is root's)."""
    p = subprocess.Popen(["setpriv", f"--reuid={STUDENT}", f"--regid={STUDENT}", "--clear-groups",
                          "sleep", "60"])
    deadline = time.monotonic() + 10
    while lockmod.process_owner(p.pid) != STUDENT and time.monotonic() < deadline:
        time.sleep(0.01)
    yield p
    p.kill()
    p.wait()


def plant(lab: LabConfig, *, user: str, uid: int, pid: int, owner: int, take_over: bool = False) -> Path:
    """A record naming `user` (`uid`, `pid`) in a file owned by `owner`, under the
    name of `uid`'s record."""
    lab.locks_dir.mkdir(parents=True, exist_ok=True)
    path = lock_path(DEVICE, lab, uid)
    # Written aside, owned, then renamed over the record in one step: a holder's
    # watch looking every 0.01 s must never see the file missing or still root's.
    aside = path.with_name(path.name + ".planting")
    aside.write_text(json.dumps({"user": user, "uid": uid, "pid": pid, "start": process_start(pid),
                                 "since": "2026-11-26T10:00:00+00:00", "session": f"{user}-1", "token": "x",
                                 "take_over": take_over}))
    os.chown(aside, owner, owner)
    os.replace(aside, path)
    return path


@root_only
def test_a_record_naming_another_user_is_forged_and_stops_nobody(lab: LabConfig) -> None:
    """stud2 writes `user teacher, pid 1`: before, everyone, root included, was told
    'the rig ... is driven by teacher (pid 1, session teacher-1)'."""
    plant(lab, user="teacher", uid=TEACHER, pid=1, owner=STUDENT)
    assert holder_of(DEVICE, lab) is None
    with DaqLock.acquire(DEVICE, lab) as lock:
        assert lock.held and (holder := holder_of(DEVICE, lab)) is not None and holder.pid == os.getpid()


@root_only
def test_a_record_naming_a_process_of_another_user_is_forged(lab: LabConfig) -> None:
    """The student names themselves but pid 1 (root's): not their process."""
    plant(lab, user="student", uid=STUDENT, pid=1, owner=STUDENT)
    assert holder_of(DEVICE, lab) is None


@root_only
def test_a_genuine_record_of_a_live_student_holds(lab: LabConfig, student_process: subprocess.Popen[bytes]) -> None:
    plant(lab, user="student", uid=STUDENT, pid=student_process.pid, owner=STUDENT)
    held = holder_of(DEVICE, lab)
    assert held is not None and (held.holder, held.pid) == ("student", student_process.pid)


@root_only
def test_the_holder_refuses_a_students_take_over(
        lab: LabConfig, student_process: subprocess.Popen[bytes]) -> None:
    """A copy of the program that skips the client's check writes a genuine
    take-over record of its student: the holder does not stop (before: 'taken over
    by ...', pumps at 0, the run ended), its record stays, and it is the holder."""
    lock = DaqLock.acquire(DEVICE, lab, session="teacher-1")
    try:
        plant(lab, user="student", uid=STUDENT, pid=student_process.pid, owner=STUDENT, take_over=True)
        assert lock.lost() is None
        assert lock.note == f"student (not an administrator) tried to take the rig at {DEVICE} over; refused"
        record = json.loads(lock_path(DEVICE, lab).read_text())
        assert (record["pid"], record["session"]) == (os.getpid(), "teacher-1")
        assert (holder := holder_of(DEVICE, lab)) is not None and holder.pid == os.getpid()
    finally:
        lock.release()


@root_only
def test_a_forged_record_does_not_end_the_holder_a_removed_one_does(lab: LabConfig) -> None:
    lock = DaqLock.acquire(DEVICE, lab)
    try:
        forged = plant(lab, user="student", uid=STUDENT, pid=os.getpid(), owner=STUDENT)  # our pid: forged
        assert forged != lock.path and lock.path.exists()  # the student's own entry, beside ours
        assert lock.lost() is None and lock.note is None
        lock.path.unlink()  # only root or our own user may, in the sticky folder: the holder stops
        assert lock.lost() == f"the lock record of the rig at {DEVICE} ({lock.path}) was removed"
    finally:
        lock.release()


def hold_flock(lab: LabConfig) -> subprocess.Popen[str]:
    """Another process holding flock on the lock folder and on the lock file (the
    lock of either design), until killed."""
    lab.locks_dir.mkdir(parents=True, exist_ok=True)
    lock_path(DEVICE, lab).touch()
    code = ("import fcntl, os, sys, time\n"
            "fds = [os.open(p, os.O_RDONLY) for p in sys.argv[1:]]\n"
            "[fcntl.flock(fd, fcntl.LOCK_EX) for fd in fds]\n"
            "print('held', flush=True)\n"
            "time.sleep(60)\n")
    p = subprocess.Popen(["python3", "-c", code, str(lab.locks_dir), str(lock_path(DEVICE, lab))],
                         stdout=subprocess.PIPE, text=True)
    assert p.stdout is not None and p.stdout.readline() == "held\n"
    return p


def test_a_held_flock_is_waited_for_a_bounded_time_then_gone_on_without_naming_its_holder(
        lab: LabConfig, monkeypatch: pytest.MonkeyPatch) -> None:
    """Before (issue 41): a student who held the locks folder's flock had every
    other student refused.  Now anyone goes on without it after LOCK_WAIT (the
    ranking decides), and the lock's note names who held it."""
    monkeypatch.setattr(lockmod, "LOCK_WAIT", 0.3)
    monkeypatch.setattr(lockmod, "is_administrator", lambda uid, lab: False)
    holder = hold_flock(lab)
    outcome: list[BaseException | DaqLock] = []

    def attempt() -> None:
        try:
            outcome.append(DaqLock.acquire(DEVICE, lab))
        except BaseException as exc:  # noqa: BLE001 - handed to the test
            outcome.append(exc)

    try:
        t = threading.Thread(target=attempt, daemon=True)
        t.start()
        t.join(20)
        assert outcome, "acquire hung on a flock someone else holds"
        lock = outcome[0]
        assert isinstance(lock, DaqLock) and lock.held
        me = lockmod.user_name(os.getuid())
        assert lock.note == (f"{lab.locks_dir}: the lock folder has been held by {me} (pid {holder.pid}) for "
                             "more than 0.3 s; this program went on without it")
        lock.release()
    finally:
        holder.kill()
        holder.wait()


def test_an_administrator_goes_on_and_a_release_does_not_wait(
        lab: LabConfig, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(lockmod, "LOCK_WAIT", 0.3)
    monkeypatch.setattr(lockmod, "QUICK_WAIT", 0.3)
    monkeypatch.setattr(lockmod, "is_administrator", lambda uid, lab: True)
    holder = hold_flock(lab)
    try:
        done = threading.Event()

        def attempt() -> None:
            with DaqLock.acquire(DEVICE, lab) as lock:   # root / an administrator
                assert lock.held
            done.set()

        t = threading.Thread(target=attempt, daemon=True)
        t.start()
        assert done.wait(20), "an administrator was stopped by a held flock"
        assert not lock_path(DEVICE, lab).exists()  # released, without the flock
    finally:
        holder.kill()
        holder.wait()


def test_flock_holders_come_from_the_kernel(tmp_path: Path) -> None:
    f = tmp_path / "f"
    f.touch()
    fd = os.open(f, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        assert (os.getpid(), lockmod.user_name(os.getuid())) in lockmod.flock_holders(fd)
    finally:
        os.close(fd)


@root_only
def test_the_watch_tells_a_refused_take_over_once_and_keeps_the_lock(
        lab: LabConfig, student_process: subprocess.Popen[bytes]) -> None:
    from quadtank_tui.session.lockwatch import LockWatch

    lock = DaqLock.acquire(DEVICE, lab)
    lost: list[str] = []
    notes: list[str] = []
    noted = threading.Event()

    def note(what: str) -> None:
        notes.append(what)
        noted.set()

    watch = LockWatch(lock, lost.append, interval=0.01, on_note=note).start()
    try:
        plant(lab, user="student", uid=STUDENT, pid=student_process.pid, owner=STUDENT, take_over=True)
        assert noted.wait(30)
        time.sleep(0.1)  # more looks: the same finding is not told again
        assert notes == [f"student (not an administrator) tried to take the rig at {DEVICE} over; refused"]
        assert lost == [] and lock.held
    finally:
        watch.stop()
        lock.release()


@root_only
def test_junk_of_another_user_hides_no_record(lab: LabConfig) -> None:
    """A student's thousand entries under the device's name (their own, and named
    as root's) are looked past: the holder is still found, and a second program refused."""
    child = subprocess.Popen(["sleep", "60"])
    try:
        lab.locks_dir.mkdir(parents=True, exist_ok=True)
        for n in range(500):
            for uid in (STUDENT, 0):
                junk = lab.locks_dir / f"{lock_path(DEVICE, lab, uid).stem}.{n}.lock"
                junk.write_text("{}")
                os.chown(junk, STUDENT, STUDENT)
        with DaqLock.acquire(DEVICE, lab) as lock:
            lock.transfer(child.pid)
            held = holder_of(DEVICE, lab)
            assert held is not None and held.pid == child.pid
            with pytest.raises(lockmod.DaqLockHeld):
                DaqLock.acquire(DEVICE, lab)
    finally:
        child.kill()
        child.wait()


@root_only
@pytest.mark.parametrize("field", ['"uid": Infinity', '"pid": 2147483648', '"pid": 1e400', '"start": -Infinity'])
def test_a_students_own_record_of_huge_numbers_blocks_nobody(lab: LabConfig, field: str) -> None:
    """A record in the student's own file (its name and owner theirs) with a number
    no C long holds: before, every acquire and holder_of of the rig ended in an
    OverflowError (from int(inf), or os.kill of pid 2**31)."""
    lab.locks_dir.mkdir(parents=True, exist_ok=True)
    path = lock_path(DEVICE, lab, STUDENT)
    fields = {"user": "stud", "uid": str(STUDENT), "pid": "1", "start": "null"}
    key = field.split(":")[0].strip('"')
    fields[key] = field.split(":", 1)[1].strip()
    path.write_text("{" + ", ".join(f'"{k}": {v}' if k != "user" else f'"{k}": "{v}"' for k, v in fields.items())
                    + ', "since": "2026-11-26T10:00:00+00:00", "token": "x"}')
    os.chown(path, STUDENT, STUDENT)
    assert holder_of(DEVICE, lab) is None
    with DaqLock.acquire(DEVICE, lab) as lock:
        assert lock.held
