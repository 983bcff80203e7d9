"""The terminal of an operator running the rig goes away: the pumps stop.

`quadtank --daq CONFIG` in a real pseudo-terminal, on a virtual rig on loopback:
Active, Run, the pumps running; then the terminal hangs up (an SSH link drops, a
tmux window is killed).  The TUI, a client, is gone; the session runs on, and -
with no unattended policy from an administrator - pauses with the pumps at 0 as
soon as its last client has left.  What counts is what the rig's own registers
say, read by a client of the test's own.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Any, Callable

import pytest

from quadtank_tui.session.client import SessionClient, stop_session_at
from quadtank_tui.files.proc import pid_alive
from quadtank_tui.session.runtime import list_sessions
from daqkit import rig_yaml

pytestmark = [pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc and Linux ptys"),
              pytest.mark.wallclock]



def _config_for(r: Any, folder: Path) -> Path:
    path = folder / "rig.yaml"
    path.write_text(rig_yaml(r.port))
    return path


def test_a_hang_up_under_active_puts_the_rigs_pumps_at_0(
        tmp_path: Path, rig: Callable[..., Any], poll: Callable[..., bool], pty_kit: Any) -> None:
    kit = pty_kit
    r = rig("--watchdog", "0")  # the rig's own last line off: the 0 must come from the session
    runtime = tmp_path / "run"
    tui = kit.Tui(tmp_path, args=("--daq", str(_config_for(r, tmp_path))),
                  env={"QUADTANK_RUNTIME": str(runtime)})
    session = None
    try:
        pid, session = tui.started_session(runtime)
        for key in (b"A", b"r"):  # Active, Run (Manual at 0.3 of full scale: both pumps on)
            os.write(tui.master, key)
            time.sleep(0.3)
        assert poll(lambda: min(r.dacs()) > 0.5, 60.0), f"the pumps never ran: {r.dacs()}"
        tui.hang_up()
        took = kit._wait_gone([pid], kit.GONE_WITHIN)
        assert took < kit.GONE_WITHIN
        assert poll(lambda: r.dacs() == (0.0, 0.0), 60.0), f"pumps still at {r.dacs()} after the hang-up"
        assert pid_alive(session.pid)  # the session runs on, paused, for its owner to come back to
        with SessionClient(session.socket, role="observer") as watcher:
            snap = watcher.snapshot()
            assert snap.operation == "Active" and snap.state == "Pause"
        note = list_sessions(runtime)[0].note
        assert "pumps at 0" in note, note
    finally:
        tui.kill()
        if session is not None and pid_alive(session.pid):
            stop_session_at(session.socket)


def test_a_private_session_puts_the_rigs_pumps_at_0_when_its_tui_is_killed(
        tmp_path: Path, rig: Callable[..., Any], poll: Callable[..., bool], pty_kit: Any) -> None:
    """`quadtank --no-session --daq`: the loop is in a private session, which ends
    with its terminal's TUI even when that one is killed outright (SIGKILL: no
    clean-up of its own; the session's lifeline ends), with the rig's pumps at 0
    and no process left.  (A hang-up, SIGHUP, SIGTERM: tests/ui/test_terminal_hangup.py.)"""
    kit = pty_kit
    r = rig("--watchdog", "0")  # the rig's own last line off: the 0 must come from the session
    runtime = tmp_path / "run"
    tui = kit.Tui(tmp_path, args=("--no-session", "--daq", str(_config_for(r, tmp_path))),
                  env={"QUADTANK_RUNTIME": str(runtime)})
    try:
        pid = tui.wait_started()
        tree = kit._tree(pid)
        assert len(tree) == 2 and list_sessions(runtime) == []  # the TUI and its unlisted session
        for key in (b"A", b"r"):  # Active, Run (Manual at 0.3 of full scale: both pumps on)
            os.write(tui.master, key)
            time.sleep(0.3)
        assert poll(lambda: min(r.dacs()) > 0.5, 60.0), f"the pumps never ran: {r.dacs()}"
        os.kill(pid, 9)
        kit._wait_gone(tree, kit.GONE_WITHIN)
        assert poll(lambda: r.dacs() == (0.0, 0.0), 60.0), f"pumps still at {r.dacs()} after the kill"
    finally:
        tui.kill()
