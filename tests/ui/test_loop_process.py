"""The TUI on a private session (what `quadtank --no-session` starts), by keys: a
parameter set in a window, Run and Automatic reach the loop in the session process,
the screen follows it, and closing the screen's client stops the loop."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
from uikit import make_app, write_params
from textual.pilot import Pilot

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.engine.runner import engine_spec
from quadtank_tui.session.client import SessionClient
from quadtank_tui.session.launch import SessionSpec, Spawned
from quadtank_tui.ui.widgets.controller_box import ElementCell
from quadtank_tui.ui.widgets.trends import Trend

pytestmark = pytest.mark.wallclock  # the TUI on a real session process


async def wait_until(pilot: Pilot, condition, timeout: float = 60.0) -> None:
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "timed out"
        await pilot.pause(0.05)


async def test_keys_drive_the_private_session_and_the_screen_follows(tmp_path: Path) -> None:
    spec = engine_spec(clock="virtual", speed=50.0, seed=1, params_dir=write_params(tmp_path / "params", PRESET),
                       logs_dir=tmp_path / "logs")
    spawned = Spawned(private=True)
    info = spawned.send(SessionSpec(spec, os.environ["QUADTANK_RUNTIME"], private=True))
    engine = SessionClient(info.socket, private=True, let_go=spawned.let_go)
    try:
        app = make_app(engine)
        async with app.run_test(size=(120, 40)) as pilot:
            await pilot.press("1", "ctrl+a", "ctrl+k", *"5.5", "enter")
            cell = app.screen.query_one("#element-0", ElementCell)
            await wait_until(pilot, lambda: "K 5.5" in str(cell.render()))
            assert engine.snapshot().params.get("CONTROLLER ONE.K") == 5.5
            await pilot.press("r", "a")
            await wait_until(pilot, lambda: app.main.snap.state == "Run" and app.main.snap.t > 5.0)
            assert app.main.snap.control == "Automatic"
            trend = app.screen.query_one("#lower", Trend)
            await wait_until(pilot, lambda: trend._history is not None and len(trend._history["t"]) > 50)
            assert trend._history is not None and trend._history["t"][-1] > 5.0
    finally:
        engine.stop()
    assert engine.ended == f"stopped by {info.owner}"  # the loop stopped in order: pumps at 0, log kept
    assert spawned.wait_ended(30.0)


def test_a_client_gone_without_a_word_stops_its_private_session(tmp_path: Path) -> None:
    """The screen's process dies (no StopSession: a SIGKILL, the terminal gone):
    the session's lifeline ends and it stops, pumps at 0, and goes."""
    spec = engine_spec(clock="virtual", speed=10.0, params_dir=write_params(tmp_path / "params", PRESET),
                       logs_dir=tmp_path / "logs")
    spawned = Spawned(private=True)
    info = spawned.send(SessionSpec(spec, os.environ["QUADTANK_RUNTIME"], private=True))
    watcher = SessionClient(info.socket, private=False)  # hears its Ended, never stops it
    try:
        spawned.let_go()
        assert watcher.wait_gone(30.0)
        assert watcher.ended == "its terminal's quadtank ended"
        assert spawned.wait_ended(30.0)
    finally:
        watcher.close()
