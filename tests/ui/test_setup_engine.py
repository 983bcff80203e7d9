"""The Setup screen on a running process: opening it, using it and leaving it
changes nothing the user did not set, and what is set takes effect bumplessly."""

from __future__ import annotations

import numpy as np
import pytest
from textual.widgets import Input

from quadtank_tui.engine.commands import Command, LogOn, LogSave, NudgeMean, SetControlMode, SetParams, SetState
from quadtank_tui.engine.runner import Engine
from quadtank_tui.files.log_reader import read_log
from quadtank_tui.ui.screens.setup import SetupScreen
from quadtank_tui.ui.widgets.setup_tables import ProcessTable

from uikit import make_app, manual_engine, open_setup  # noqa: E402
from quadtank_tui.ui.screens.main import MainScreen

H = 0.1  # the default sampling time, s


def ok(engine: Engine, command: Command) -> None:
    result = engine.submit(command).result()
    assert result.ok, result.message


def start_experiment(engine: Engine) -> None:
    """Manual, inputs 0.32 / 0.28 (so the levels move), logging t y1..y4 u1 u2."""
    ok(engine, SetParams({"LOGGING.Variables": "t y1 y2 y3 y4 u1 u2", "LOGGING.Points": 600,
                          "REFERENCE ONE.Mean": 0.32, "REFERENCE TWO.Mean": 0.28}))
    ok(engine, SetState("Run"))
    ok(engine, LogOn())


async def test_switching_to_setup_and_back_leaves_the_process_alone(setup_engine: Engine) -> None:
    # The same experiment twice: once while a user goes from Main to Setup, opens
    # and cancels windows there and comes back; once untouched.  The logs must be
    # identical.
    engine = setup_engine
    start_experiment(engine)
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        engine.run_for(10.0)
        await open_setup(pilot)
        assert isinstance(app.screen, SetupScreen)
        engine.run_for(10.0)
        for key in ("h", "enter", "escape", "s", "escape", "i", "escape", "1", "escape", "f", "escape"):
            await pilot.press(key)
            engine.run_for(2.0)
        await pilot.press("escape")  # back
        await pilot.pause()
        assert isinstance(app.screen, MainScreen)
        engine.run_for(18.0)
    ok(engine, LogSave("with_setup"))

    twin = manual_engine()
    start_experiment(twin)
    twin.run_for(60.0)
    ok(twin, LogSave("without"))
    twin.stop()

    log, ref = read_log("logs/with_setup.log"), read_log("logs/without.log")
    assert log.rows == ref.rows == 600
    assert np.array_equal(log.data, ref.data)
    t = log["t"]
    assert np.allclose(np.diff(t), H, atol=1e-9)  # no gap
    assert set(log["u1"]) == {0.32} and set(log["u2"]) == {0.28}  # no jump
    assert engine.snapshot().params == twin.snapshot().params


async def test_a_sampling_time_change_mid_run_is_bumpless(setup_engine: Engine) -> None:
    engine = setup_engine
    app = make_app(engine)
    ok(engine, SetState("Run"))
    engine.run_for(20.0)
    ok(engine, SetControlMode("Automatic"))
    ok(engine, NudgeMean(1, 0.05))  # a reference step, so the controllers are working
    engine.run_for(20.0)
    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        await pilot.press("s")
        field = app.screen.query_one(Input)
        assert field.value == "100"
        await pilot.press("ctrl+a", "ctrl+k", "5", "0", "0", "enter")
        await pilot.pause()
        assert isinstance(app.screen, SetupScreen)
        assert engine.snapshot().params.tsamp_ms == 500.0
        engine.run_for(5.0)
    h = engine.history(8.0)
    t, u1, u2 = h["t"], h["u1"], h["u2"]
    dt = np.diff(t)
    change = int(np.argmax(dt > 0.3))  # first step at the new sampling time
    assert np.allclose(dt[:change], 0.1) and np.allclose(dt[change:], 0.5)  # the time axis stays right
    # u moves over the first 0.5 s sample about as much as over five 0.1 s samples
    # before it (measured: 7.9e-4 against 2.4e-4 per 0.1 s): no bump.
    typical = max(np.abs(np.diff(u1[:change])).max(), np.abs(np.diff(u2[:change])).max())
    allowed = 2 * typical * 0.5 / 0.1
    assert abs(u1[change + 1] - u1[change]) < allowed and abs(u2[change + 1] - u2[change]) < allowed
    assert t[-1] == pytest.approx(44.5)  # 400 samples of 0.1 s, then 10 of 0.5 s


async def test_setup_is_built_once_and_shows_what_changed_while_away(setup_engine: Engine) -> None:
    # Main keeps the Setup screen between visits (composing it again cost 230-390 ms
    # at each S): coming back it shows the parameters in use now, not those of the
    # last visit, at the terminal's size now, with no table chosen.
    engine = setup_engine
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        setup = app.screen
        assert isinstance(setup, SetupScreen)
        assert "100 ms" in str(setup.query_one("#sampling").render())
        assert not setup.has_class("-compact")
        await pilot.press("h")  # the process table chosen, then back to Main
        assert app.focused is setup.query_one("#process")
        await pilot.press("escape")
        await pilot.pause()
        assert isinstance(app.screen, MainScreen)
        # Changed while away: a file loaded, another client's Set, the terminal.
        ok(engine, SetParams({"SAMPLING TIME.TSamp": 200, "SIMULATION.Valve1": 0.5}))
        ok(engine, SetState("Run"))
        engine.run_for(3.0)
        await pilot.resize_terminal(100, 30)
        await pilot.pause()
        await pilot.press("S")
        await pilot.pause()
        assert app.screen is setup  # the same screen, not built again
        assert "200 ms" in str(setup.query_one("#sampling").render())
        assert "t = 3.0 s" in str(setup.query_one("#setup-status").render())
        process = setup.query_one("#process", ProcessTable)
        assert process.params == engine.snapshot().params
        assert str(process.get_row_at(0)[-1]) == "0.50", process.get_row_at(0)  # tank 1: gamma 1
        assert setup.has_class("-compact") and app.focused is None
        # Its timer runs again (every 0.25 s): a sample taken while it is in front shows.
        engine.run_for(1.0)
        for _ in range(50):  # 0.3 s on an idle machine; a loaded one may take longer
            await pilot.pause(0.1)
            if "t = 4.0 s" in str(setup.query_one("#setup-status").render()):
                break
        assert "t = 4.0 s" in str(setup.query_one("#setup-status").render())
        await pilot.press("S")
        await pilot.pause()
        assert isinstance(app.screen, MainScreen)
