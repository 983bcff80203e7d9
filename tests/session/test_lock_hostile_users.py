"""The DAQ lock against another local user who misbehaves (the review of issue 24,
with two real users on the virtual rig): removing the holder's record, a lab file
of their own, a directory at the lock's name, a locks folder made first and shut.
Users are made with useradd (root only, skipped otherwise) and removed after."""

from __future__ import annotations

import argparse
import os
import shutil
import stat
import subprocess
import time
from pathlib import Path
from typing import Iterator

import pytest
from otherusers import ROOT, made_users
from otherusers import as_user as run_as
from test_two_users import HOLD, ask
from test_two_users import shared as shared_folder

from quadtank_tui.commands import UsageError
from quadtank_tui.commands import lab as lab_command
from quadtank_tui.session.lab import LabConfig
from quadtank_tui.session.lock import DaqLock, holder_of, lock_path

pytestmark = pytest.mark.skipif(os.getuid() != 0 or shutil.which("useradd") is None
                                or shutil.which("runuser") is None, reason="needs root, useradd and runuser")

DEVICE = "127.0.0.1:15021/1"
shared = shared_folder  # the fixture: a folder every user may write


@pytest.fixture(scope="module")
def users() -> Iterator[tuple[str, ...]]:
    with made_users(f"qtl{os.getpid()}a", f"qtl{os.getpid()}b") as names:
        yield names


def as_user(user: str, shared: Path, code: str, *args: str, **env: str) -> subprocess.Popen[str]:
    return run_as(user, code, *args, cwd=shared, env={"QUADTANK_RUNTIME": str(shared / "rt"), **env})


def holding(user: str, shared: Path, **env: str) -> subprocess.Popen[str]:
    p = as_user(user, shared, HOLD, DEVICE, **env)
    assert p.stdout is not None and p.stdout.readline() == "held\n", p.communicate()[1]
    return p


def finish(p: subprocess.Popen[str]) -> tuple[str, str]:
    out, err = p.communicate(timeout=60)
    return out, err


#: stud2 removes every lock record it can (as `rm -f` in a loop did), then starts a run.
REMOVE_AND_START = """
    import os, sys
    from quadtank_tui.session.lab import load_lab_config
    from quadtank_tui.session.lock import DaqLock, DaqLockHeld
    lab = load_lab_config()
    for name in sorted(os.listdir(lab.locks_dir)):
        try:
            os.unlink(os.path.join(lab.locks_dir, name))
            print("removed", name)
        except OSError as exc:
            print("kept", exc.strerror)
    try:
        DaqLock.acquire(sys.argv[1], lab)
        print("won")
    except DaqLockHeld as exc:
        print("refused", exc.holder)
"""


def test_removing_the_holders_record_starts_no_second_run(users: tuple[str, str], shared: Path) -> None:
    """Before: the record removed, stud2 got the lock, and both programs restored
    their own record every 0.5 s while both drove the pumps."""
    stud1, stud2 = users
    holder = holding(stud1, shared)
    try:
        out, err = finish(as_user(stud2, shared, REMOVE_AND_START, DEVICE))
        assert out == f"kept Operation not permitted\nrefused {stud1}\n", err
        assert ask(holder) == "ours | -"
    finally:
        holder.kill()
        holder.wait()


#: A copy that skips the flock and writes its own genuine record, naming an old
#: process of its user and an early `since`: it must see that it lost.
RACE = """
    import os, sys, secrets
    from datetime import datetime
    from quadtank_tui.session import lock as lockmod
    from quadtank_tui.session.lab import load_lab_config
    lab = load_lab_config()
    me = lockmod.current_user()
    rec = lockmod._Record(me.user, me.uid, me.pid, lockmod.process_start(me.pid),
                          datetime(2000, 1, 1).astimezone(), None, secrets.token_hex(8))
    path = lockmod.lock_path(sys.argv[1], lab)
    lockmod._put(path, rec)
    print(lockmod.DaqLock(sys.argv[1], path, rec, lab).lost(), flush=True)
    sys.stdin.readline()
"""


def test_of_two_live_records_the_first_written_holds(users: tuple[str, str], shared: Path) -> None:
    """Ranked by the files' change time (the kernel's), not by a `since` or a pid
    the student writes: the later program stops, the holder drives on and says so."""
    stud1, stud2 = users
    holder = holding(stud1, shared)
    racer = as_user(stud2, shared, RACE, DEVICE)
    try:
        assert racer.stdout is not None
        lost = racer.stdout.readline()
        assert lost.startswith(f"the rig at {DEVICE} is driven by {stud1} (pid ") and \
            lost.endswith(", and that program started first\n"), racer.stderr
        answer = ask(holder)
        assert answer.startswith(f"ours | {stud2} (pid ") and \
            answer.endswith(f"started on the rig at {DEVICE} after this program; it must stop")
        held = holder_of(DEVICE, LabConfig(runtime_dir=shared / "rt"))
        assert held is not None and held.holder == stud1
    finally:
        for p in (holder, racer):
            p.kill()
            p.wait()


def rig_config(folder: Path) -> Path:
    cfg = folder / "rig.yaml"
    cfg.write_text((ROOT / "params" / "virtual-rig.yaml").read_text().replace("port: 5020", "port: 15021"))
    os.chmod(cfg, 0o644)
    return cfg


TAKE_OVER = """
    import sys
    from quadtank_tui.commands import lab
    lab.TAKE_OVER_WAIT = 1.0
    try:
        with lab.hold_daq(sys.argv[1], take_over=True):
            print("drives")
    except Exception as exc:
        print(type(exc).__name__, exc)
"""


def test_a_lab_file_of_a_students_own_gives_no_take_over(users: tuple[str, str], shared: Path) -> None:
    """Before: stud2's own lab file (admin_group: their group) let `--take-over`
    through; the holder refused, and after TAKE_OVER_WAIT both drove."""
    stud1, stud2 = users
    mylab = shared / "mylab.yaml"
    mylab.write_text(f"admin_group: {stud2}\n")
    shutil.chown(mylab, stud2, stud2)
    holder = holding(stud1, shared)
    try:
        out, err = finish(as_user(stud2, shared, TAKE_OVER, str(rig_config(shared)), QUADTANK_LAB=str(mylab)))
        assert out.startswith(f"NotPermitted taking over the rig at {DEVICE} from {stud1} needs an administrator ")
        assert f"the lab file {mylab} is {stud2}'s, not root's, so it gives no one rights); you are {stud2}\n" in out
        assert ask(holder) == "ours | -"
    finally:
        holder.kill()
        holder.wait()


def test_a_holder_that_does_not_yield_keeps_the_rig(users: tuple[str, str], shared: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """A take-over the holder did not yield to (by its own lab's rules; here it does
    not even look): the taker gives the lock back and refuses after TAKE_OVER_WAIT
    (before: it drove beside the holder)."""
    stud1 = users[0]
    monkeypatch.setenv("QUADTANK_RUNTIME", str(shared / "rt"))
    monkeypatch.delenv("QUADTANK_LAB", raising=False)
    monkeypatch.setattr(lab_command, "TAKE_OVER_WAIT", 0.3)
    holder = holding(stud1, shared)
    try:
        with pytest.raises(UsageError) as caught:
            with lab_command.hold_daq(str(rig_config(shared)), take_over=True, say=lambda line: None):
                pytest.fail("drove beside a holder that did not yield")
        assert str(caught.value).startswith(f"the holder refused the take-over: {stud1} (pid ")
        assert f"still drives the rig at {DEVICE} after 0.3 s" in str(caught.value)
        held = holder_of(DEVICE, LabConfig(runtime_dir=shared / "rt"))
        assert held is not None and held.holder == stud1  # given back
        assert not lock_path(DEVICE, LabConfig(runtime_dir=shared / "rt")).exists()  # root's record gone
        assert ask(holder) == "ours | -"
    finally:
        holder.kill()
        holder.wait()


BLOCK = """
    import os, re, sys
    from quadtank_tui.session.lab import load_lab_config
    lab = load_lab_config()
    stem = re.sub(r"[^A-Za-z0-9.-]", "_", sys.argv[1])
    for uid in sys.argv[2:]:   # the old name, every user's name: directories with a file inside
        os.makedirs(lab.locks_dir / (stem + ("" if uid == "-" else f"~{uid}") + ".lock") / "x")
    print("blocked", flush=True)
"""


def test_a_directory_at_the_locks_name_blocks_nobody(users: tuple[str, str], shared: Path) -> None:
    """Before: a directory at the lock's name blocked everyone, root included."""
    stud1, stud2 = users  # (shared/rt: the lab's runtime folder, made by `quadtank lab init`)
    uid1 = str(subprocess.run(["id", "-u", stud1], capture_output=True, text=True).stdout.strip())
    out, err = finish(as_user(stud2, shared, BLOCK, DEVICE, "-", uid1, "0"))
    assert out == "blocked\n", err
    holder = holding(stud1, shared)
    holder.kill()
    holder.wait()
    with DaqLock.acquire(DEVICE, LabConfig(runtime_dir=shared / "rt")) as lock:
        assert lock.held


SHUT = """
    import os, sys
    os.makedirs(sys.argv[1] + "/locks")
    os.chmod(sys.argv[1], 0o755)
    os.chmod(sys.argv[1] + "/locks", 0o755)
"""


def test_a_shared_folder_made_first_and_shut_is_named_and_fixed_by_root(users: tuple[str, str],
                                                                         shared: Path) -> None:
    """Before: whoever made the runtime folder and locks/ first owned them (could
    empty or shut them).  Now a folder of a student's is nobody's lab folder: the
    others are refused naming its owner, and `quadtank lab init` makes it root's
    (1755; users/ and locks/ 1777 sticky)."""
    stud1, stud2 = users
    rt = shared / "rt2"
    finish(as_user(stud2, shared, SHUT, str(rt)))
    out, err = finish(as_user(stud1, shared, HOLD, DEVICE, QUADTANK_RUNTIME=str(rt)))
    assert out == "" and (f"{rt}: the runtime folder is {stud2}'s with mode 755: not a lab folder (root's or an "
                          "administrator's, writable by its owner only)") in err
    start = time.monotonic()
    assert lab_command.cmd_lab_init(argparse.Namespace(lab=None, folder=str(rt))) == 0  # root
    for folder, mode in ((rt, 0o1755), (rt / "users", 0o1777), (rt / "locks", 0o1777)):
        st = os.stat(folder)
        assert (st.st_uid, stat.S_IMODE(st.st_mode)) == (0, mode)
    assert time.monotonic() - start < 5
    holder = holding(stud1, shared, QUADTANK_RUNTIME=str(rt))
    holder.kill()
    holder.wait()
