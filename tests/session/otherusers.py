"""Real other users for the two-user tests and benchmarks/hardening_locks.py:
made with useradd (root only) and removed after, and programs run as them.

Where the interpreter is out of their reach (a Python under /root, mode 0700) a
program starts as root, imports what it needs and then drops to the user's uid and
gid itself (setgroups, setgid, setuid) before it runs: the kernel sees that user
from then on (file owners, /proc, SO_PEERCRED), as with runuser."""

from __future__ import annotations

import contextlib
import os
import pwd
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Iterator

ROOT = Path(__file__).resolve().parents[2]

#: Runs sys.argv[3] as uid sys.argv[1], gid sys.argv[2], after importing (as root)
#: what the programs of the tests and the benchmark need.
DROP = """
import argparse, fcntl, gettext, ipaddress, json, locale, os, secrets, sys, textwrap, time
import quadtank_tui.cli, quadtank_tui.commands.lab, quadtank_tui.session.lab, quadtank_tui.session.lock
import quadtank_tui.session.policy, quadtank_tui.session.roles, quadtank_tui.session.riglock
import quadtank_tui.daq.config, quadtank_tui.session.lockwatch
import encodings.idna, encodings.latin_1, encodings.utf_8_sig
quadtank_tui.cli.build_parser()  # argparse's own imports (gettext, locale)
uid, gid = int(sys.argv[1]), int(sys.argv[2])
os.setgroups([])
os.setgid(gid)
os.setuid(uid)
code, sys.argv = sys.argv[3], [sys.argv[0]] + sys.argv[4:]
exec(compile(code, "<as-user>", "exec"), {"__name__": "__main__"})
"""


@contextlib.contextmanager
def made_users(*names: str) -> Iterator[tuple[str, ...]]:
    """The users `names`, created for the block (useradd, no home) and removed after."""
    made = []
    try:
        for name in names:
            subprocess.run(["useradd", "--no-create-home", "--shell", "/bin/sh", name], check=True,
                           capture_output=True)
            made.append(name)
        yield names
    finally:
        for name in made:
            subprocess.run(["userdel", name], capture_output=True)


def _reachable(user: str) -> bool:
    """Whether `user` may run this interpreter with runuser (not under /root)."""
    return subprocess.run(["runuser", "-u", user, "--", sys.executable, "-c", "pass"],
                          capture_output=True).returncode == 0


def as_user(user: str, code: str, *args: str, cwd: Path | str = "/",
            env: dict[str, str] | None = None) -> subprocess.Popen[str]:
    """`code` (a Python program, dedented) run as `user` with `args`, pipes on
    stdin, stdout and stderr; the worktree's package on its path."""
    code = textwrap.dedent(code)
    env = {"PATH": os.environ.get("PATH", ""), "PYTHONPATH": str(ROOT), "PYTHONDONTWRITEBYTECODE": "1",
           "NO_COLOR": "1", **(env or {})}
    if _reachable(user):
        argv = ["runuser", "-u", user, "--", sys.executable, "-c", code, *args]
    else:
        entry = pwd.getpwnam(user)
        argv = [sys.executable, "-c", DROP, str(entry.pw_uid), str(entry.pw_gid), code, *args]
    return subprocess.Popen(argv, cwd=cwd, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
