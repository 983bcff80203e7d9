"""The DAQ locks' folder against two real students (issue 41, items 6 and 7): it
is made by an administrator (`quadtank lab init`: root's, 1777 sticky, in a
runtime folder of root's, 1755), so a student can neither make it first, nor
replace it with a link, nor remove another's lock record.  Users are made with
useradd (root only, skipped otherwise) and removed after."""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
from pathlib import Path
from typing import Iterator

import pytest
from otherusers import made_users
from otherusers import as_user as run_as
from test_two_users import HOLD
from test_two_users import shared as shared_folder

from quadtank_tui.commands import lab as lab_command

pytestmark = [pytest.mark.skipif(os.getuid() != 0 or shutil.which("useradd") is None
                                 or shutil.which("runuser") is None, reason="needs root, useradd and runuser"),
              pytest.mark.wallclock]

DEVICE = "127.0.0.1:15031/1"
shared = shared_folder  # a folder every user may write, and shared/rt made by init_lab_folder


@pytest.fixture(scope="module")
def users() -> Iterator[tuple[str, ...]]:
    with made_users(f"qtp{os.getpid()}a", f"qtp{os.getpid()}b") as names:
        yield names


def as_user(user: str, shared: Path, code: str, *args: str, runtime: Path | None = None,
            **env: str) -> subprocess.Popen[str]:
    return run_as(user, code, *args, cwd=shared,
                  env={"QUADTANK_RUNTIME": str(runtime or shared / "rt"), "HOME": str(shared), **env})


def held(user: str, shared: Path, **kw: object) -> subprocess.Popen[str]:
    p = as_user(user, shared, HOLD, DEVICE, **kw)  # type: ignore[arg-type]
    assert p.stdout is not None and p.stdout.readline() == "held\n", p.communicate()[1]
    return p


def look(holder: subprocess.Popen[str]) -> str:
    assert holder.stdin is not None and holder.stdout is not None
    holder.stdin.write("look\n")
    holder.stdin.flush()
    return holder.stdout.readline().split(" | ")[0]


def stop(p: subprocess.Popen[str]) -> None:
    p.kill()
    p.wait()


#: alice against bob's lock: every way to remove it, replace the folder, or make another.
ATTACK = """
    import json, os, sys
    rt, lock = sys.argv[1], sys.argv[2]
    tries = {"remove bob's record": lambda: os.unlink(lock),
             "rename bob's record": lambda: os.rename(lock, rt + "/locks/mine.lock"),
             "write bob's record": lambda: open(lock, "w").write("{}"),
             "rename locks/": lambda: os.rename(rt + "/locks", rt + "/old-locks"),
             "make a locks link": lambda: os.symlink("/tmp", rt + "/locks2"),
             "make the runtime folder's entries": lambda: os.mkdir(rt + "/users2")}
    out = {}
    for what, do in tries.items():
        try:
            do()
            out[what] = "done"
        except OSError as exc:
            out[what] = type(exc).__name__
    print(json.dumps(out), flush=True)
"""


def test_a_student_cannot_remove_or_replace_anothers_lock(users: tuple[str, str], shared: Path) -> None:
    """Before: bob's run left `drwxrwxrwt bob bob locks`; alice could make it
    herself, and removing bob's lock record put his pumps at 0 within 0.26 s ("the
    rig was taken over") and gave her the rig."""
    alice, bob = users
    rt = shared / "rt"
    holder = held(bob, shared)
    try:
        (lock,) = [p for p in (rt / "locks").iterdir() if p.name.endswith(".lock")]
        attack = as_user(alice, shared, ATTACK, str(rt), str(lock))
        out, err = attack.communicate(timeout=60)
        assert set(json.loads(out).values()) == {"PermissionError"}, (out, err)
        assert look(holder) == "ours"  # bob still drives the rig
        st = os.lstat(rt / "locks")
        assert (st.st_uid, st.st_mode & 0o7777) == (0, 0o1777)
        second = as_user(alice, shared, HOLD, DEVICE)
        out, err = second.communicate(timeout=60)
        assert out == "" and f"the rig at {DEVICE} is driven by {bob} (pid " in err
    finally:
        stop(holder)


def test_a_students_own_runtime_folder_or_a_lab_folder_not_made_is_nobodys(users: tuple[str, str],
                                                                            shared: Path) -> None:
    """A runtime folder alice made (with a locks/ of hers, 1777: she could empty
    it) is refused by bob, naming her; a lab file's runtime folder that nobody
    made yet is not made by the first student (an administrator's, `lab init`)."""
    alice, bob = users
    hers = shared / "alices"
    make = as_user(alice, shared, """
        import os, sys
        os.makedirs(sys.argv[1] + "/locks")
        os.chmod(sys.argv[1] + "/locks", 0o1777)
    """, str(hers))
    assert make.communicate(timeout=60)[0] == ""
    p = as_user(bob, shared, HOLD, DEVICE, runtime=hers)
    out, err = p.communicate(timeout=60)
    assert out == "" and f"{hers}: the runtime folder is {alice}'s with mode 755: not a lab folder" in err
    labfile = shared / "lab.yaml"
    labfile.write_text(f"runtime_dir: {shared / 'fresh'}\n")
    p = as_user(bob, shared, HOLD, DEVICE, QUADTANK_LAB=str(labfile))
    out, err = p.communicate(timeout=60)
    assert out == "" and (f"{shared / 'fresh'}: the lab's runtime folder is not there; an administrator makes "
                          "it once with `quadtank lab init`") in err
    assert not (shared / "fresh").exists()


def test_a_planted_locks_link_blocks_until_lab_init_and_never_after(users: tuple[str, str], shared: Path) -> None:
    """Before: alice's `locks -> /home/alice` in the 1777 runtime folder refused
    every run, root's included, with no way out but finding it.  In an old
    layout's folder (1777) it is named (`quadtank lab init` repairs it); once
    repaired, the runtime folder is root's 1755 and she cannot plant it again."""
    alice, bob = users
    old = shared / "old"
    old.mkdir()
    os.chmod(old, 0o1777)
    plant = as_user(alice, shared, "import os, sys; os.symlink(sys.argv[2], sys.argv[1] + '/locks')",
                    str(old), str(shared))
    assert plant.communicate(timeout=60)[1] == ""
    p = as_user(bob, shared, HOLD, DEVICE, runtime=old)
    out, err = p.communicate(timeout=60)
    assert out == "" and "an administrator makes it with `quadtank lab init" in err
    assert lab_command.cmd_lab_init(argparse.Namespace(lab=None, folder=str(old))) == 0  # root, once
    assert (old / "locks").is_dir() and not (old / "locks").is_symlink()
    holder = held(bob, shared, runtime=old)
    try:
        again = as_user(alice, shared, "import os, sys; os.symlink('/tmp', sys.argv[1] + '/locks2')", str(old))
        assert "PermissionError" in again.communicate(timeout=60)[1]
        assert look(holder) == "ours"
    finally:
        stop(holder)
