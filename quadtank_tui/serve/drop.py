"""The first code of a browser tab's process: become the tab's user, then run `quadtank`.

`quadtank serve` starts this module as its own user (root, or a system user with
CAP_SETUID and CAP_SETGID) with a clean environment; it imports the client's modules
first (so an interpreter the user cannot reach, a Python under /root, still runs the
TUI), then takes the user's groups, group and uid for good (setgroups, setgid,
setuid: the kernel sees that user from then on - file owners, SO_PEERCRED on the
session's socket, /proc), checks that root cannot be had back, moves to the user's
home and runs `quadtank` with the arguments it was given, as `python -m quadtank_tui`
would.  Nothing of the server's (its files, its environment, its capabilities)
reaches the user's program: setuid to a non-zero uid clears every capability.

    python -m quadtank_tui.serve.drop UID GID GROUPS HOME -- QUADTANK-ARGS...

GROUPS is a comma-separated list of group ids (may be empty).
"""

from __future__ import annotations

import importlib
import os
import runpy
import sys

#: What the client imports lazily, loaded before the drop (a stdlib the user
#: cannot read would fail later).  Importing is all: nothing runs.
PRELOAD: tuple[str, ...] = (
    "quadtank_tui.cli",
    "quadtank_tui.commands.sessions",
    "quadtank_tui.session.client",
    "quadtank_tui.session.launch",
    "quadtank_tui.session.runtime",
    "quadtank_tui.ui.app",
    "textual.drivers.web_driver",
    "textual.widgets",
    "encodings.idna",
    "encodings.latin_1",
    "encodings.utf_8_sig",
)


def drop_to(uid: int, gid: int, groups: list[int]) -> None:
    """The process as `uid`/`gid` with `groups`, for good; SystemExit if any step fails
    or root could be had back (then nothing of the user's runs as root)."""
    if uid == 0 or gid == 0:
        raise SystemExit("quadtank serve: refusing to run a tab as root")
    if os.getuid() != uid or os.geteuid() != uid:
        os.setgroups(groups)
        os.setresgid(gid, gid, gid)
        os.setresuid(uid, uid, uid)
    if os.getresuid() != (uid, uid, uid) or os.getresgid() != (gid, gid, gid):
        raise SystemExit("quadtank serve: the switch to the tab's user failed")
    try:
        os.setuid(0)
    except PermissionError:
        return
    raise SystemExit("quadtank serve: root could be had back after the switch; stopping")


def main(argv: list[str]) -> int:
    if len(argv) < 5 or argv[4] != "--":
        print("usage: python -m quadtank_tui.serve.drop UID GID GROUPS HOME -- ARGS...", file=sys.stderr)
        return 2
    uid, gid = int(argv[0]), int(argv[1])
    groups = [int(g) for g in argv[2].split(",") if g]
    home = argv[3]
    for name in PRELOAD:
        try:
            importlib.import_module(name)
        except ImportError:  # an optional part missing: the client says so itself
            pass
    drop_to(uid, gid, groups)
    try:
        os.chdir(home)
    except OSError:
        os.chdir("/")
    sys.argv = ["quadtank", *argv[5:]]
    runpy.run_module("quadtank_tui", run_name="__main__", alter_sys=True)
    return 0


if __name__ == "__main__":  # pragma: no cover - the tab's process
    raise SystemExit(main(sys.argv[1:]))
