"""The TUI on its loop process (what `make run` starts), by keys: a parameter set in
a window, Run and Automatic reach the loop, and the screen follows it."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from uikit import make_app, write_params
from textual.pilot import Pilot

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.engine.process import EngineProcess
from quadtank_tui.engine.runner import engine_spec
from quadtank_tui.ui.widgets.controller_box import ElementCell
from quadtank_tui.ui.widgets.trends import Trend

pytestmark = pytest.mark.wallclock  # the TUI on a real loop process


async def wait_until(pilot: Pilot, condition, timeout: float = 60.0) -> None:  # type: ignore[no-untyped-def]
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "timed out"
        await pilot.pause(0.05)


async def test_keys_drive_the_loop_process_and_the_screen_follows(tmp_path: Path) -> None:
    engine = EngineProcess(engine_spec(clock="virtual", speed=50.0, seed=1,
                                       params_dir=write_params(tmp_path / "params", PRESET),
                                       logs_dir=tmp_path / "logs"))
    try:
        app = make_app(engine)
        engine.start()
        async with app.run_test(size=(120, 40)) as pilot:
            await pilot.press("1", "ctrl+a", "ctrl+k", *"5.5", "enter")
            cell = app.screen.query_one("#element-0", ElementCell)
            await wait_until(pilot, lambda: "K 5.5" in str(cell.render()))
            assert engine.snapshot().params.get("CONTROLLER ONE.K") == 5.5
            await pilot.press("r", "a")
            await wait_until(pilot, lambda: app.main.snap.state == "Run" and app.main.snap.t > 5.0)
            assert app.main.snap.control == "Automatic"
            trend = app.screen.query_one("#lower", Trend)
            await wait_until(pilot, lambda: len(trend._history["t"]) > 50)
            assert trend._history["t"][-1] > 5.0
    finally:
        engine.stop()
    assert engine.snapshot().state == "Pause"
