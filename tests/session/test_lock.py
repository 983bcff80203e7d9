"""The DAQ lock: one holder per device, named in a file every user can read; a
dead holder's lock is taken over; two processes racing for it cannot both win."""

from __future__ import annotations

import json
import multiprocessing
import os
import pickle
import signal
import stat
import subprocess
import sys
import textwrap
from datetime import datetime
from pathlib import Path

import pytest

from quadtank_tui.session.lab import LabConfig
from quadtank_tui.session.lock import (
    DaqLock, DaqLockHeld, device_key, holder_of, lock_path, process_start,
)
from quadtank_tui.session.roles import current_user

DEVICE = device_key("192.0.2.7", 502, 1)


@pytest.fixture
def lab(tmp_path: Path) -> LabConfig:
    return LabConfig(runtime_dir=tmp_path / "rt")


def hold_in_child(lab: LabConfig, session: str | None = None) -> subprocess.Popen[str]:
    """Another program holding the lock: a child that prints 'held' and waits."""
    code = textwrap.dedent(f"""
        import sys
        from pathlib import Path
        from quadtank_tui.session.lab import LabConfig
        from quadtank_tui.session.lock import DaqLock
        lock = DaqLock.acquire({DEVICE!r}, LabConfig(runtime_dir=Path({str(lab.runtime_dir)!r})),
                               session={session!r})
        print("held", flush=True)
        sys.stdin.readline()
        lock.release()
        print("released", flush=True)
    """)
    child = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             text=True)
    assert child.stdout is not None and child.stdout.readline() == "held\n"
    return child


def test_file_names_the_holder(lab: LabConfig) -> None:
    with DaqLock.acquire(DEVICE, lab, session="s-3") as lock:
        path = lock_path(DEVICE, lab)
        assert path == lock.path == lab.runtime_dir / "locks" / f"192.0.2.7_502_1~{os.getuid()}.lock"
        st = os.stat(path)
        assert stat.S_IMODE(st.st_mode) == 0o644 and st.st_uid == os.getuid()  # others read, only we write
        assert stat.S_IMODE(os.stat(lab.locks_dir).st_mode) == 0o1777  # sticky: nobody removes another's
        record = json.loads(path.read_text())
        me = current_user()
        assert (record["user"], record["uid"], record["pid"], record["session"]) == (me.user, me.uid, me.pid, "s-3")
        assert record["start"] == process_start(me.pid) is not None
        assert datetime.fromisoformat(record["since"]) == lock.since
        assert (holder := holder_of(DEVICE, lab)) is not None and holder.pid == os.getpid()
    assert not path.exists()  # released
    assert holder_of(DEVICE, lab) is None


def test_a_second_program_is_refused_with_the_holders_name(lab: LabConfig) -> None:
    child = hold_in_child(lab, session="s-3")
    try:
        with pytest.raises(DaqLockHeld) as caught:
            DaqLock.acquire(DEVICE, lab)
        held = caught.value
        assert (held.pid, held.uid, held.session, held.holder) == (child.pid, os.getuid(), "s-3", current_user().user)
        assert str(held) == (f"the rig at 192.0.2.7:502/1 is driven by {current_user().user} "
                             f"(pid {child.pid}, session s-3) since {held.since:%H:%M}")
        holder = holder_of(DEVICE, lab)
        assert holder is not None and holder.pid == child.pid
        again = pickle.loads(pickle.dumps(held))  # crosses a process boundary intact
        assert (str(again), again.pid, again.since) == (str(held), held.pid, held.since)
        assert child.stdin is not None and child.stdout is not None
        child.stdin.write("\n")
        child.stdin.flush()
        assert child.stdout.readline() == "released\n"
    finally:
        child.kill()
        child.wait()
    with DaqLock.acquire(DEVICE, lab) as lock:
        assert lock.pid == os.getpid()


def test_a_sigkilled_holders_lock_is_taken_over(lab: LabConfig) -> None:
    child = hold_in_child(lab)
    os.kill(child.pid, signal.SIGKILL)
    child.wait()
    assert json.loads(lock_path(DEVICE, lab).read_text())["pid"] == child.pid  # its record is left
    assert holder_of(DEVICE, lab) is None
    with DaqLock.acquire(DEVICE, lab) as lock:
        assert lock.pid == os.getpid()
        assert json.loads(lock_path(DEVICE, lab).read_text())["pid"] == os.getpid()


def test_a_recycled_pid_is_not_the_holder(lab: LabConfig) -> None:
    """A record naming a live pid whose start time differs: the pid was reused."""
    lab.locks_dir.mkdir(parents=True, exist_ok=True)
    record = {"user": "ghost", "uid": os.getuid(), "pid": os.getppid(), "start": 1, "since": "2026-01-01T10:00:00+00:00",
              "session": None, "token": "t"}
    lock_path(DEVICE, lab).write_text(json.dumps(record))
    assert holder_of(DEVICE, lab) is None
    record["start"] = process_start(os.getppid())
    lock_path(DEVICE, lab).write_text(json.dumps(record))
    holder = holder_of(DEVICE, lab)
    assert holder is not None and holder.holder == "ghost"
    with pytest.raises(DaqLockHeld, match="driven by ghost .* since 2026-01-01 10:00"):
        DaqLock.acquire(DEVICE, lab)


def test_take_over_and_the_old_holders_release(lab: LabConfig) -> None:
    child = hold_in_child(lab)
    try:
        mine = DaqLock.acquire(DEVICE, lab, take_over=True)
        assert mine.held and (holder := holder_of(DEVICE, lab)) is not None and holder.pid == os.getpid()
    finally:
        assert child.stdin is not None
        child.stdin.write("\n")
        child.stdin.flush()
        child.wait()
    # the old holder's release left our record alone
    assert json.loads(lock_path(DEVICE, lab).read_text())["pid"] == os.getpid()
    mine.release()
    mine.release()  # idempotent
    assert not lock_path(DEVICE, lab).exists()


def test_transfer_to_the_session_process(lab: LabConfig) -> None:
    lock = DaqLock.acquire(DEVICE, lab, session="s-1")
    child = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.readline()"], stdin=subprocess.PIPE)
    try:
        lock.transfer(child.pid)
        lock.release()  # the launcher leaving does not free the rig
        held = holder_of(DEVICE, lab)
        assert held is not None and (held.pid, held.session, held.since) == (child.pid, "s-1", lock.since)
        with pytest.raises(DaqLockHeld):
            DaqLock.acquire(DEVICE, lab)
    finally:
        child.kill()
        child.wait()
    assert holder_of(DEVICE, lab) is None  # the session died: stale


def test_the_same_process_adopts_its_transferred_lock(lab: LabConfig) -> None:
    first = DaqLock.acquire(DEVICE, lab)
    second = DaqLock.acquire(DEVICE, lab, session="s-9")  # e.g. after transfer(os.getpid())
    assert second.since == first.since and not first.held and second.held
    first.release()
    assert second.held
    second.release()


def _contend(runtime_dir: str, barrier: multiprocessing.synchronize.Barrier, out: multiprocessing.Queue) -> None:
    lab = LabConfig(runtime_dir=Path(runtime_dir))
    barrier.wait()
    try:
        DaqLock.acquire(DEVICE, lab)
        out.put(("won", os.getpid()))
    except DaqLockHeld as exc:
        out.put(("refused", exc.pid))
    barrier.wait()  # hold it until everyone tried


def test_processes_racing_for_it_one_wins(lab: LabConfig) -> None:
    ctx = multiprocessing.get_context("fork")
    n = 6
    barrier, out = ctx.Barrier(n), ctx.Queue()
    procs = [ctx.Process(target=_contend, args=(str(lab.runtime_dir), barrier, out)) for _ in range(n)]
    for p in procs:
        p.start()
    results = [out.get(timeout=60) for _ in procs]
    for p in procs:
        p.join(60)
    winners = [pid for what, pid in results if what == "won"]
    assert len(winners) == 1
    assert all(pid == winners[0] for what, pid in results if what == "refused")
    assert holder_of(DEVICE, lab) is None  # the winner exited without release: stale


def test_a_symlink_is_not_a_lock_file(lab: LabConfig, tmp_path: Path) -> None:
    """A planted link is no record: it is replaced (renamed over), never followed."""
    lab.locks_dir.mkdir(parents=True, exist_ok=True)
    (tmp_path / "victim").write_text(json.dumps({"user": "x", "uid": os.getuid(), "pid": os.getppid(),
                                                 "since": "2026-01-01T10:00:00+00:00"}))
    lock_path(DEVICE, lab).symlink_to(tmp_path / "victim")
    assert holder_of(DEVICE, lab) is None
    with DaqLock.acquire(DEVICE, lab) as lock:  # a name of its own beside the link
        assert lock.held and lock.path != lock_path(DEVICE, lab) and not lock.path.is_symlink()
    assert lock_path(DEVICE, lab).is_symlink()
    assert json.loads((tmp_path / "victim").read_text())["user"] == "x"


def test_broken_record_counts_as_free(lab: LabConfig) -> None:
    lab.locks_dir.mkdir(parents=True, exist_ok=True)
    lock_path(DEVICE, lab).write_text("{not json")
    with DaqLock.acquire(DEVICE, lab) as lock:
        assert lock.held


def test_lost_says_who_took_it(lab: LabConfig) -> None:
    first = DaqLock.acquire(DEVICE, lab)
    assert first.lost() is None
    second = DaqLock.acquire(DEVICE, lab, take_over=True)
    reason = first.lost()
    assert reason is not None and reason.startswith(
        f"the rig at {DEVICE} was taken over by {current_user().user} (pid {os.getpid()}) at ")
    second.release()
    assert second.lost() == "the lock was released"


def test_lock_watch_calls_back_once_when_taken_over(lab: LabConfig) -> None:
    import threading

    from quadtank_tui.session.lockwatch import LockWatch

    lock = DaqLock.acquire(DEVICE, lab)
    calls: list[str] = []
    called = threading.Event()

    def call(why: str) -> None:
        calls.append(why)
        called.set()

    watch = LockWatch(lock, call, interval=0.01).start()
    assert not called.wait(0.1)  # still ours: no call
    DaqLock.acquire(DEVICE, lab, take_over=True)
    assert called.wait(30.0)
    watch.stop()
    assert len(calls) == 1 and "was taken over by" in calls[0] and watch.reason == calls[0]


def test_an_exited_unreaped_holder_is_not_alive(lab: LabConfig) -> None:
    """A holder that exited but whose parent has not reaped it yet (a zombie)."""
    child = hold_in_child(lab)
    os.kill(child.pid, signal.SIGKILL)
    import time

    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        with open(f"/proc/{child.pid}/stat", "rb") as f:
            if b") Z " in f.read():
                break
        time.sleep(0.01)
    assert holder_of(DEVICE, lab) is None
    child.wait()
