"""The thesis's sample session (appendix A.4) and the bumpless switch, by keys
alone, on the engine with a manual clock; and the Main screen it leaves.

A.4 runs at a sampling time of 1 s (600 points = 10 min); the sampling time is a
Setup-screen value, so the session starts from a default.par that has it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from uikit import Recording, make_app
from textual.pilot import Pilot

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.engine import commands as c
from quadtank_tui.files.log_reader import read_log
from quadtank_tui.ui.app import QuadTankApp
from quadtank_tui.ui.widgets.input_signals import ChannelPanel
from quadtank_tui.ui.widgets.process_image import ProcessImage
from quadtank_tui.ui.windows.logging import LoggingWindow
from quadtank_tui.ui.windows.signals import InputSignalWindow

SESSION = PRESET.with_value("SAMPLING TIME.TSamp", 1000.0)
STEP = 0.1


def typed(text: str) -> list[str]:
    """Keys that replace a text field's content with `text`."""
    return ["ctrl+a", "ctrl+k", *text]


async def settle(pilot: Pilot, engine: Recording, seconds: float) -> None:
    """Let process time pass, then let the screen catch up."""
    engine.run_for(seconds)
    assert isinstance(pilot.app, QuadTankApp)
    pilot.app.main.refresh_view()
    await pilot.pause()


async def test_sample_session_a4_by_keys(make_engine: Any) -> None:
    engine = make_engine(SESSION)
    logs = engine.logs_dir
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        # 1. Manual control mode (Simul: no rig here).
        await pilot.press("m")
        # 2. Decentralized PID; PI (3.0, 30) upper left, (2.7, 40) lower right.
        await pilot.press("t", "1")
        await pilot.press("1", *typed("3.0"), "tab", *typed("30"), "enter")
        await pilot.press("4", *typed("2.7"), "tab", *typed("40"), "enter")
        # 3. Both inputs constant at 0.30, Run, wait for the steady state.
        await pilot.press("i", *typed("0.30"), "enter", "I", *typed("0.30"), "enter", "r")
        await settle(pilot, engine, 300.0)
        # Logging: 600 points into data.log, LogOn, close the window.
        await pilot.press("l", *typed("600"), "tab", *typed("data"), "ctrl+o")
        await pilot.pause()
        assert isinstance(app.screen, LoggingWindow)
        await pilot.press("escape")
        # 4. Automatic, then reference 1 := its value + 0.1 with the text box.
        await pilot.press("a")
        await settle(pilot, engine, 1.0)
        panel = app.main.query_one("#channel-1", ChannelPanel)
        assert str(panel.border_title).startswith("ref1")
        await pilot.press("i")
        window = app.screen
        assert isinstance(window, InputSignalWindow)
        ref1 = float(window.field_widget("REFERENCE ONE.Mean").value)
        await pilot.press(*typed(f"{ref1 + STEP:.6f}"), "enter")
        # 5. Run until all data is collected; reopen Logging, Save.
        await settle(pilot, engine, 600.0)
        await pilot.press("l")
        assert "100%" in str(app.screen.query_one("#progress").render()) or \
            engine.snapshot().log.progress == 1.0
        await pilot.press("ctrl+s")
        await pilot.pause()
        await pilot.press("escape")
        # 6. Exit (the log is saved: nothing to discard).
        await pilot.press("q", "y")
        await pilot.pause()
    assert app.return_code == 0
    assert engine.sent(c.LogDiscard) == []
    p = engine.snapshot().params
    assert (p.control.family.value, p.control.structure.value) == ("PID", "Decentralized")
    assert [p.get(f"CONTROLLER {n}.{k}") for n in ("ONE", "FOUR") for k in ("K", "Ti", "I", "D")] == [
        3.0, 30.0, True, False, 2.7, 40.0, True, False]

    log = read_log(logs / "data.log")
    assert log.variables == ("y1", "y2", "u1", "u2")
    assert log.tsamp == 1.0
    assert log.rows == 600
    y1, y2 = log["y1"], log["y2"]
    y10, y20 = float(np.mean(y1[:2])), float(np.mean(y2[:2]))
    r1 = ref1 + STEP
    # The step is in it: y1 moves 0.1 (2 cm) to the new reference...
    assert abs(y10 - ref1) < 0.005 and abs(float(np.mean(y1[-60:])) - r1) < 0.002
    # ... as published for P- with these PIs: overshoot under 10 %, settled in
    # about a minute (within 5 % of the step after 120 s), y2 back where it was.
    overshoot = (float(y1.max()) - r1) / STEP
    assert overshoot < 0.10
    late = np.abs(y1[120:] - r1)
    assert float(late.max()) < 0.05 * STEP
    assert abs(float(np.mean(y2[-60:])) - y20) < 0.003
    # The inputs did the work and stayed in range.
    assert float(log["u1"].max()) <= 1.0 and float(log["u1"][-1]) > float(log["u1"][0])


async def test_bumpless_switch_on_screen_and_in_the_log(make_engine: Any) -> None:
    engine = make_engine(SESSION)
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("i", *typed("0.33"), "enter", "r")   # off the operating point
        await settle(pilot, engine, 200.0)
        await pilot.press("l", *typed("100"), "ctrl+o", "escape")
        await settle(pilot, engine, 20.0)
        image = app.main.query_one(ProcessImage)
        before = str(image.render())
        y1 = engine.snapshot().y[0]
        await pilot.press("a")
        await settle(pilot, engine, 1.0)
        after = str(image.render())
        # On screen: the pumps' inputs did not move; ref1 took the level.
        assert "P1 0.330" in before and "P1 0.330" in after
        assert str(app.main.query_one("#channel-1", ChannelPanel).border_title).startswith("ref1")
        assert abs(engine.snapshot().params.get("REFERENCE ONE.Mean") - y1) < 0.002
        await settle(pilot, engine, 79.0)
        await pilot.press("l", "ctrl+s", "escape")
        await pilot.pause()
    log = read_log(engine.logs_dir / "data.log")
    assert log.rows == 100
    u1, u2 = log["u1"], log["u2"]
    # In the log: no jump at the switch (row 20) or after; u stays at its value.
    assert float(np.abs(np.diff(u1)).max()) < 0.002
    assert float(np.abs(np.diff(u2)).max()) < 0.002
    assert abs(float(u1[-1]) - 0.33) < 0.005


def session_in_automatic(engine: Recording):
    """The A.4 session by commands (the keys are tested above): Manual at the
    operating point for 120 s, Automatic, ref1 + 0.1, 180 s more: t = 300 s."""
    async def before(pilot: Pilot) -> None:
        for command in (c.SetParams({"LOGGING.Points": 600}), c.SetState("Run")):
            engine.submit(command)
        engine.run_for(120.0)
        engine.submit(c.LogOn())
        engine.submit(c.SetControlMode("Automatic"))
        engine.run_for(1.0)
        mean = engine.snapshot().params.get("REFERENCE ONE.Mean")
        engine.submit(c.SetParams({"REFERENCE ONE.Mean": round(mean + STEP, 6)}))
        await settle(pilot, engine, 179.0)
    return before


def test_main_after_300_s_of_the_session_in_automatic(snap_compare, make_engine: Any) -> None:
    engine = make_engine(SESSION)
    assert snap_compare(make_app(engine), terminal_size=(120, 40),
                        run_before=session_in_automatic(engine))
