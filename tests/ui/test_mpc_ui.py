"""The MPC in the TUI: the Type window's row, the Controller box, its window."""

from __future__ import annotations

from typing import Any, Callable

import pytest
from textual.widgets import Input

from uikit import Recording, make_app

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.engine.commands import ResetControllers, SetControlMode, SetParams, SetState
from quadtank_tui.ui.widgets.controller_box import MPCCell
from quadtank_tui.ui.windows.mpc import MPCWindow

MPC = PRESET.with_values({"CONTROL.Type": "MPC"})


def test_main_with_mpc_80x24(snap_compare, make_engine: Callable[..., Recording]) -> None:
    assert snap_compare(make_app(make_engine(MPC)), terminal_size=(80, 24))


def test_mpc_window_80x24(snap_compare, make_engine: Callable[..., Recording]) -> None:
    assert snap_compare(make_app(make_engine(MPC)), terminal_size=(80, 24), press=["1"])


def test_mpc_window_120x40(snap_compare, make_engine: Callable[..., Recording]) -> None:
    assert snap_compare(make_app(make_engine(MPC)), terminal_size=(120, 40), press=["1"])


async def test_choosing_mpc_shows_it_and_its_window_applies_a_horizon(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("t", "6")
        await pilot.pause()
        assert engine.sent(SetParams)[-1].values == {"CONTROL.Type": "MPC"}
        app.main.refresh_view()
        await pilot.pause()
        cell = app.main.query_one(MPCCell)
        assert cell.display and "N 30 Nu 30" in str(cell.render())
        await pilot.press("1")
        await pilot.pause()
        assert isinstance(app.screen, MPCWindow)
        app.screen.field_widget("MPC.Horizon").focus()
        await pilot.press("end", "ctrl+u", "4", "0", "tab", "end", "ctrl+u", "1", "tab",
                          "end", "ctrl+u", "1", "5", "enter")  # a burst
        await pilot.pause()
        assert engine.sent(SetParams)[-1].values == {"MPC.Horizon": 40, "MPC.Step": 1.0, "MPC.ControlHorizon": 15}
        app.main.refresh_view()
        await pilot.pause()
        info = engine.snapshot().mpc
        assert info is not None and (info.horizon, info.moves, info.step_s) == (40, 15, pytest.approx(1.0))
        assert "N 40x1s Nu 15" in str(app.main.query_one(MPCCell).render())  # 40 steps of 10 samples
        await pilot.press("t", "1")  # back to PID
        await pilot.pause()
        assert engine.sent(SetParams)[-1].values == {"CONTROL.Type": "PID", "CONTROL.Structure": "Decentralized"}
        assert engine.snapshot().mpc is None


async def test_a_control_horizon_past_the_horizon_is_refused_at_its_field(make_engine: Any) -> None:
    engine = make_engine(MPC)
    app = make_app(engine)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("1")
        await pilot.pause()
        sent = len(engine.sent(SetParams))
        assert isinstance(app.screen, MPCWindow)
        horizon = app.screen.field_widget("MPC.ControlHorizon")
        assert isinstance(horizon, Input)
        horizon.value = "50"
        await pilot.press("enter")
        await pilot.pause()
        assert isinstance(app.screen, MPCWindow) and len(engine.sent(SetParams)) == sent
        assert "50 is longer than the horizon (30)" in str(app.screen.query_one("#e-2").render())  # its row
        assert engine.snapshot().params.mpc.control_horizon == 0
        before = len(engine.commands)  # Reset: the whole controller's states, nothing else; the window closes
        await pilot.click("#reset_integrators")
        await pilot.pause()
        assert engine.commands[before:] == [ResetControllers()] and not isinstance(app.screen, MPCWindow)


async def test_switching_a_running_loop_from_pi_to_mpc_and_back_has_no_bump(engine: Recording) -> None:
    """The keys a user presses (t 6, t 1) on a running, settled PI loop in Automatic:
    the pumps move less than 0.005 of full scale at each switch sample."""
    for command in (SetState("Run"), SetControlMode("Automatic")):
        assert engine.submit(command).result().ok
    engine.run_for(300.0)
    app = make_app(engine)
    async with app.run_test(size=(80, 24)) as pilot:
        for keys, family in ((("t", "6"), "MPC"), (("t", "1"), "PID")):
            before = engine.snapshot().u
            await pilot.press(*keys)
            await pilot.pause()
            assert engine.snapshot().params.control.family.value == family
            engine.run_for(0.1)
            after = engine.snapshot().u
            assert max(abs(a - b) for a, b in zip(after, before)) < 0.005, (family, before, after)
            engine.run_for(5.0)


async def test_the_window_edits_disturbance_measured_and_slack_weight_by_keys(make_engine: Any) -> None:
    """Typed like a user: a wrong model, a tank the plant lacks and an unmeasured
    tracked tank are refused at their field (nothing sent); then a burst of valid
    edits is sent as one SetParams and the engine designs with it."""
    engine = make_engine(MPC)
    app = make_app(engine)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("1")
        await pilot.pause()
        window = app.screen
        assert isinstance(window, MPCWindow)
        keys = [f.key for f in window.fields]
        sent = len(engine.sent(SetParams))

        async def type_into(key: str, text: str) -> None:
            window.field_widget(key).focus()
            await pilot.press("end", "ctrl+u", *text)

        def error(key: str) -> str:
            return str(window.query_one(f"#e-{keys.index(key)}").render())

        for key, text, reason in (
                ("MPC.Disturbance", "state", "must be one of input, output; got 'state'"),
                ("MPC.Measured", "1 2 5", "the quadtank plant has 4 tanks, got tank 5"),
                ("MPC.Measured", "1 3", "tracked tank(s) [2] must be measured")):
            await type_into(key, text)
            await pilot.press("enter")
            await pilot.pause()
            assert app.screen is window and len(engine.sent(SetParams)) == sent, (key, text)
            assert reason in error(key), (key, text, error(key))
            assert isinstance(window, MPCWindow)  # (the `is` above narrowed it to a Screen)
            window.field_widget(key).value = str(window.params.get(key))  # back to the value in force
        await type_into("MPC.Disturbance", "Output")
        await pilot.press("tab", "end", "ctrl+u", *"1 2", "tab", "end", "ctrl+u", *"500", "enter")  # a burst
        await pilot.pause()
        assert engine.sent(SetParams)[-1].values == {
            "MPC.Disturbance": "output", "MPC.Measured": "1 2", "MPC.SlackWeight": 500.0}
        mpc = engine.snapshot().params.mpc
        assert (mpc.disturbance, mpc.measured, mpc.slack_weight) == ("output", "1 2", 500.0)
        assert engine.snapshot().mpc is not None  # designed and running with them
