"""`quadtank --daq CONFIG` / `--par FILE` while the caller's session runs: the TUI
attaches to it, and its first window says so at once, with what that session
drives and that the options are not in force; `n` asks for a new session, Enter
keeps the running one (issue 43)."""

from __future__ import annotations

import argparse
from typing import Any

from textual.widgets import Static

from quadtank_tui.commands.sessions import attached_notice
from quadtank_tui.session.info import SessionInfo
from quadtank_tui.ui.app import build_app
from quadtank_tui.ui.screens.main import MainScreen
from quadtank_tui.ui.windows.attached import AttachedWindow

RUNNING = SessionInfo(id="s7", owner="ann", uid=1000, pid=1, started="2026-12-02T01:00:00", plant="quadtank")


def test_the_notice_names_the_session_its_plant_and_the_options_not_applied() -> None:
    args = argparse.Namespace(daq_global="params/virtual-rig.yaml", tui_par="minphase.par")
    notice = attached_notice(RUNNING, args)
    assert notice.session == "s7"
    assert notice.plant == "the simulator (Simul)"
    assert notice.ignored == ("--daq params/virtual-rig.yaml", "--par minphase.par")
    rig = attached_notice(SessionInfo(**{**RUNNING.__dict__, "daq": "/lab/rig1.yaml", "operation": "Active"}),
                          argparse.Namespace(daq_global=None, tui_par="p.par"))
    assert rig.plant == "the rig of /lab/rig1.yaml (Active)"
    assert rig.ignored == ("--par p.par",)


async def _press_in_the_window(engine: Any, key: str) -> tuple[Any, type]:
    """The TUI as `quadtank --daq ...` opens it on a running session; `key` pressed in
    its first window; the app and the screen in front afterwards."""
    args = argparse.Namespace(daq_global="params/virtual-rig.yaml", tui_par=None)
    app = build_app(engine, refresh_interval=0.05, wall_clock=lambda: 0.0, attached=attached_notice(RUNNING, args))
    async with app.run_test(size=(100, 30)) as pilot:
        await pilot.pause()
        await pilot.pause()
        window = app.screen
        assert isinstance(window, AttachedWindow)
        text = str(window.query_one("#attached-text", Static).render())
        assert "Attached to your running session s7, whose plant is the simulator (Simul)" in text
        assert "--daq params/virtual-rig.yaml apply to a new session only: they are NOT in force here" in text
        assert "quadtank stop s7, then quadtank --daq params/virtual-rig.yaml" in text
        await pilot.press(key)
        await pilot.pause()
        front = type(app.screen)
    return app, front


async def test_enter_keeps_the_running_session(engine: Any) -> None:
    app, front = await _press_in_the_window(engine, "enter")
    assert front is MainScreen
    assert not app.new_session_asked


async def test_n_asks_for_a_new_session_and_ends_this_screen(engine: Any) -> None:
    app, _ = await _press_in_the_window(engine, "n")
    assert app.new_session_asked
    assert app.return_code == 0
