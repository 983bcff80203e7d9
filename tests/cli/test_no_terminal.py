"""`quadtank` (the screen) without a terminal says so in one line, points to
`quadtank run`, exits 2 and starts nothing: no session, no loop (issue 24: a
traceback, exit 1, and a session left running, orphaned)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a POSIX shell's <&-")


@pytest.mark.parametrize("redirect, missing", [
    ("<&-", "stdin is closed"),
    ("--no-session <&-", "stdin is closed"),
    ("--no-session < /dev/null > out.txt", "stdin is not one"),
], ids=["stdin closed", "stdin closed, no session", "stdin and stdout files"])
def test_the_screen_without_a_terminal_is_one_line_exit_2_and_starts_nothing(
        tmp_path: Path, redirect: str, missing: str) -> None:
    runtime = tmp_path / "run"
    env = {**os.environ, "QUADTANK_RUNTIME": str(runtime), "PYTHON": sys.executable}
    p = subprocess.run(["sh", "-c", f'exec "$PYTHON" -m quadtank_tui {redirect}'], cwd=tmp_path, env=env,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, timeout=120)
    assert p.returncode == 2, p.stderr
    assert p.stderr.splitlines() == [f"quadtank: error: the screen needs a terminal and {missing}; a headless "
                                     "experiment runs with `quadtank run` (quadtank run --help)"]
    # Nothing was started: a session writes its record before it says it is ready.
    place = runtime / "users" / str(os.getuid())  # this user's folder of sessions
    assert not place.exists() or sorted(q.name for q in place.iterdir()) == []
