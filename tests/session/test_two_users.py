"""Two real users (issue 24): roles and the DAQ lock decided where they cannot be
forged.  Created with useradd when the tests run as root (CI does), removed after;
skipped otherwise.  The programs run as them (otherusers.as_user: runuser, or a
drop to their uid where the interpreter is under /root), from the worktree, with a
temporary folder of their own for the runtime folder and files."""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Iterator

import pytest
from otherusers import ROOT, made_users
from otherusers import as_user as run_as

from quadtank_tui.session.folders import init_lab_folder

pytestmark = pytest.mark.skipif(os.getuid() != 0 or shutil.which("useradd") is None
                                or shutil.which("runuser") is None, reason="needs root, useradd and runuser")


@pytest.fixture(scope="module")
def users() -> Iterator[tuple[str, ...]]:
    with made_users(f"qtr{os.getpid()}a", f"qtr{os.getpid()}b") as names:
        yield names


@pytest.fixture
def shared() -> Iterator[Path]:
    """A folder every user may write (tmp_path is root's, 0700)."""
    folder = Path(tempfile.mkdtemp(prefix="qtr-"))
    os.chmod(folder, 0o1777)
    init_lab_folder(folder / "rt")  # the lab's runtime folder, as `quadtank lab init` makes it
    yield folder
    shutil.rmtree(folder, ignore_errors=True)


def as_user(user: str, shared: Path, code: str, *args: str, cwd: Path | None = None) -> subprocess.Popen[str]:
    return run_as(user, code, *args, cwd=cwd or shared,
                  env={"QUADTANK_RUNTIME": str(shared / "rt"), "HOME": str(shared)})


def test_a_student_in_a_folder_of_their_own_is_not_an_administrator(users: tuple[str, str], shared: Path) -> None:
    """Before: 'administrator: yes' (they may write ./params/default.par)."""
    stud1 = users[0]
    own = shared / "own"
    (own / "params").mkdir(parents=True)
    shutil.copy(ROOT / "params" / "default.par", own / "params" / "default.par")
    shutil.chown(own, stud1)
    shutil.chown(own / "params", stud1)
    shutil.chown(own / "params" / "default.par", stud1)
    p = as_user(stud1, shared, "import sys; from quadtank_tui.cli import main; sys.exit(main(['lab']))", cwd=own)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 0, err
    you = next(line for line in out.splitlines() if line.startswith("you "))
    assert you.endswith("administrator: no"), out
    assert f"administrators  someone who may write {ROOT / 'params' / 'default.par'}" in out


HOLD = """
    import sys, time
    from pathlib import Path
    from quadtank_tui.session.lab import load_lab_config
    from quadtank_tui.session.lock import DaqLock
    lab = load_lab_config()
    lock = DaqLock.acquire(sys.argv[1], lab, session="run-1")
    print("held", flush=True)
    for line in sys.stdin:   # each line: look at the lock (as LockWatch does)
        print(lock.lost() or "ours", "|", lock.note or "-", flush=True)
"""

#: A copy of the program that skips every check and writes its own record over the
#: holder's (what `run --daq --take-over` from a modified copy does).
FORCE = """
    import sys
    from quadtank_tui.session import lock as lockmod
    from quadtank_tui.session.lab import load_lab_config
    lockmod.is_administrator = lambda uid, lab: True   # the copy's own idea of who may
    lockmod.DaqLock.acquire(sys.argv[1], load_lab_config(), take_over=True)
    print("forced", flush=True)
    sys.stdin.readline()
"""

DEVICE = "127.0.0.1:15020/1"


def ask(p: subprocess.Popen[str]) -> str:
    assert p.stdin is not None and p.stdout is not None
    p.stdin.write("\n")
    p.stdin.flush()
    return p.stdout.readline().strip()


def test_a_student_cannot_take_the_rig_from_another(users: tuple[str, str], shared: Path) -> None:
    """Before: stud2's forced take-over ended stud1's run ('taken over by ...')."""
    stud1, stud2 = users
    holder = as_user(stud1, shared, HOLD, DEVICE)
    forcer = None
    try:
        assert holder.stdout is not None and holder.stdout.readline() == "held\n", holder.stderr
        assert ask(holder) == "ours | -"
        forcer = as_user(stud2, shared, FORCE, DEVICE)
        assert forcer.stdout is not None and forcer.stdout.readline() == "forced\n"
        answer = ask(holder)
        assert answer == f"ours | {stud2} (not an administrator) tried to take the rig at {DEVICE} over; refused"
        from quadtank_tui.session.lab import LabConfig
        from quadtank_tui.session.lock import holder_of

        held = holder_of(DEVICE, LabConfig(runtime_dir=shared / "rt"))
        assert held is not None and held.holder == stud1 and held.pid in (holder.pid, _child_pid(holder.pid))
    finally:
        for p in (holder, forcer):
            if p is not None:
                p.kill()
                p.wait()


def _child_pid(runuser_pid: int) -> int:
    """The python runuser started (runuser forks, then waits for it)."""
    kids = Path(f"/proc/{runuser_pid}/task/{runuser_pid}/children").read_text().split()
    return int(kids[0]) if kids else runuser_pid


FORGE = """
    import json, os, sys
    from pathlib import Path
    from quadtank_tui.session.lab import ensure_runtime_dir, load_lab_config
    from quadtank_tui.session.lock import lock_path
    lab = load_lab_config()
    ensure_runtime_dir(lab)
    path = lock_path(sys.argv[1], lab)
    path.write_text(json.dumps({"user": "teacher", "uid": 0, "pid": 1, "since": "2026-11-26T10:00:00+00:00",
                                "session": "teacher-1", "token": "x"}))
    os.chmod(path, 0o600)   # and nobody may read it
    print("forged", flush=True)
"""


def test_a_forged_record_stops_nobody_and_a_held_flock_is_named(users: tuple[str, str], shared: Path) -> None:
    """Before: 'the rig ... is driven by teacher (pid 1, session teacher-1)' for
    everyone, root included; and a flock held by stud2 hung stud1 without a word."""
    stud1, stud2 = users
    forger = as_user(stud2, shared, FORGE, DEVICE)
    out, err = forger.communicate(timeout=120)
    assert out == "forged\n", err
    take = as_user(stud1, shared, HOLD, DEVICE)
    try:
        assert take.stdout is not None and take.stdout.readline() == "held\n", take.stderr
    finally:
        take.kill()
        take.wait()
    # stud2 holds the lock folder's flock: stud1 (no administrator) goes on without it in bounded time
    # (issue 41: it was refused, so one student blocked every other)
    hostage = as_user(stud2, shared, """
        import fcntl, os, sys, time
        fd = os.open(sys.argv[1], os.O_RDONLY)
        fcntl.flock(fd, fcntl.LOCK_EX)
        print("holding", flush=True)
        time.sleep(120)
    """, str(shared / "rt" / "locks"))
    try:
        assert hostage.stdout is not None and hostage.stdout.readline() == "holding\n"
        start = time.monotonic()
        holder = as_user(stud1, shared, HOLD, DEVICE)
        try:
            assert holder.stdout is not None and holder.stdout.readline() == "held\n"
            waited = time.monotonic() - start
            assert holder.stdin is not None
            holder.stdin.write("look\n")
            holder.stdin.flush()
            said = holder.stdout.readline()
            assert said.startswith("ours | ") and f"the lock folder has been held by {stud2} (pid " in said
            assert waited < 60
        finally:
            holder.kill()
            holder.wait()
    finally:
        hostage.kill()
        hostage.wait()


def test_a_student_with_a_copy_of_their_own_cannot_take_the_rig_over(users: tuple[str, str], shared: Path) -> None:
    """The issue's case: stud2 ran `run --daq ... --take-over` from a copy (a folder
    of their own whose params/default.par they may write) and ended stud1's Active
    run.  Now stud2 is no administrator there: refused, exit 2, stud1 still holds."""
    stud1, stud2 = users
    copy = shared / "copy"
    (copy / "params").mkdir(parents=True)
    shutil.copy(ROOT / "params" / "default.par", copy / "params" / "default.par")
    text = (ROOT / "params" / "virtual-rig.yaml").read_text().replace("port: 5020", "port: 15020")
    (copy / "rig.yaml").write_text(text)
    for path in (copy, copy / "params", copy / "params" / "default.par", copy / "rig.yaml"):
        shutil.chown(path, stud2)
    holder = as_user(stud1, shared, HOLD, DEVICE)
    try:
        assert holder.stdout is not None and holder.stdout.readline() == "held\n", holder.stderr
        taker = as_user(stud2, shared, """
            import sys
            from quadtank_tui.cli import main
            sys.exit(main(["run", "--daq", "rig.yaml", "--realtime", "--duration", "5", "--log", "x.log",
                           "--par", "params/default.par", "--take-over"]))
        """, cwd=copy)
        out, err = taker.communicate(timeout=120)
        assert taker.returncode == 2, err
        assert err == (f"quadtank: error: taking over the rig at 127.0.0.1:15020/1 from {stud1} needs an "
                       f"administrator (someone who may write {ROOT / 'params' / 'default.par'}); "
                       f"you are {stud2}\n")
        assert ask(holder) == "ours | -"
        assert not (copy / "x.log").exists()
    finally:
        holder.kill()
        holder.wait()
