"""The Main screen driven by keys and clicks (App.run_test), on the engine.

What is checked is what reached the engine (the commands) and what the screen
shows afterwards.
"""

from __future__ import annotations

import pytest
from uikit import Recording, make_app

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.engine import commands as c
from quadtank_tui.engine.sim import SimBackend
from quadtank_tui.ui.widgets.controller_box import ElementCell
from quadtank_tui.ui.widgets.process_image import ProcessImage
from quadtank_tui.ui.widgets.trends import Trend
from quadtank_tui.ui.windows.base import ChoiceWindow, ConfirmWindow
from quadtank_tui.ui.windows.controller_windows import PIDWindow
from quadtank_tui.ui.windows.process import TankWindow
from quadtank_tui.ui.windows.signals import InputSignalWindow, PlotTypeWindow


async def test_mode_keys_send_mode_commands(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("r", "a", "m", "p", "R")
        await pilot.pause()
    assert engine.commands == [c.SetState("Run"), c.SetControlMode("Automatic"),
                             c.SetControlMode("Manual"), c.SetState("Pause"), c.SetState("Reset")]


async def test_window_cancel_keeps_and_set_applies(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("1")
        assert isinstance(app.screen, PIDWindow)
        await pilot.press("ctrl+a", "ctrl+k", *"5.5", "escape")          # Cancel
        assert engine.snapshot().params.get("CONTROLLER ONE.K") == 3.0
        assert engine.sent(c.SetParams) == []
        await pilot.press("1")
        await pilot.press("ctrl+a", "ctrl+k", *"5.5", "enter")           # Set
        await pilot.pause()
        assert engine.snapshot().params.get("CONTROLLER ONE.K") == 5.5
        assert engine.sent(c.SetParams) == [c.SetParams({"CONTROLLER ONE.K": 5.5})]
        cell = app.screen.query_one("#element-0", ElementCell)
        assert "K 5.5" in str(cell.render())


async def test_enter_sets_from_a_switch_and_type_keys_choose(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("1", "tab", "tab", "tab", "space", "enter")   # Integral off, Set
        await pilot.pause()
        assert app.screen is app.main
        await pilot.press("t", "down", "down", "enter")                 # General decentralized
        await pilot.pause()
    assert engine.sent(c.SetParams) == [
        c.SetParams({"CONTROLLER ONE.I": False}),
        c.SetParams({"CONTROL.Type": "General", "CONTROL.Structure": "Decentralized"})]


async def test_opener_key_closes_its_window(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("g")
        await pilot.press("g")
        assert app.screen is app.main
        await pilot.press("t", "t")
        assert app.screen is app.main
    assert engine.commands == []


async def test_refused_value_keeps_the_old_one(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("1")
        window = app.screen
        await pilot.press("tab", "ctrl+a", "ctrl+k", "minus", "3", "enter")  # Ti = -3
        await pilot.pause()
        assert app.screen is window, "the window stays open on a bad value"
        assert "Ti" in str(window.query_one("#e-1").render()) or "must be" in str(window.query_one("#e-1").render())
        await pilot.press("ctrl+a", "ctrl+k", *"abc", "enter")             # not a number
        assert "not a number" in str(window.query_one("#e-1").render())
        await pilot.press("escape")
        assert engine.snapshot().params.get("CONTROLLER ONE.Ti") == 30.0
        assert engine.sent(c.SetParams) == []
        # A refusal by the engine itself comes back as a notification.
        app.main.send(c.SetParams({"REFERENCE ONE.Mean": 5.0}))
        await pilot.pause()
        assert any("REFERENCE ONE.Mean" in n.message for n in app._notifications)
        assert engine.snapshot().params.get("REFERENCE ONE.Mean") == 0.3


async def test_active_unavailable_without_daq_says_why(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("A")
        await pilot.pause()
        said = [n.message for n in app._notifications]
        assert len(said) == 1 and "no DAQ" in said[0] and "--daq CONFIG" in said[0]
        assert "--daq" in app.main.active_bindings["A"].binding.tooltip
        assert engine.snapshot().operation == "Simul"
    assert engine.sent(c.SetOperation) == []


async def test_active_offered_with_a_daq(make_engine) -> None:
    class Rig(SimBackend):
        """The simulator standing in for a rig behind a DAQ link."""

        kind = "Active"

    engine = make_engine(daq=Rig(PRESET.quadtank_constants(), PRESET.simulation.operating_levels()))
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        assert app.main.check_action("active", ()) is True
        await pilot.press("A")
        await pilot.pause()
        engine.run_for(0.1)
    assert engine.snapshot().operation == "Active"


async def test_add_water_shows_in_level_and_trend(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("r")
        engine.run_for(10.0)
        await pilot.press("h")
        assert isinstance(app.screen, TankWindow)
        before = engine.snapshot().y[0]
        await pilot.press("1", *"0.2", "enter")  # 1 chooses the tank, then the amount
        await pilot.pause()
        assert engine.sent(c.AddWater) == [c.AddWater(1, 0.2)]
        engine.run_for(0.1)  # poured in at the next sample
        app.main.refresh_view()
        image = app.main.query_one(ProcessImage)
        level = engine.snapshot().y[0]
        assert level > before + 0.19
        assert f"1:{level:.2f}" in str(image.render())
        lower = app.main.query_one("#lower", Trend)
        assert lower._history is not None and abs(lower._history["y1"][-1] - level) < 1e-12


async def test_click_on_tank_and_element_opens_their_windows(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        image = app.main.query_one(ProcessImage)
        box = next(b for b in image._boxes if b.action == "tank(3)")
        await pilot.click(ProcessImage, offset=(box.x0 + 2, box.y0 + 1))
        assert isinstance(app.screen, TankWindow) and app.screen.selected == 3
        await pilot.press("escape")
        await pilot.click("#element-3")
        assert isinstance(app.screen, PIDWindow) and app.screen.index == 3


async def test_unused_elements_do_not_open(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("2")
        assert app.screen is app.main
        await pilot.click("#element-1")
        assert app.screen is app.main


async def test_input_keys_nudge_step_and_toggle(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("right_square_bracket", "left_curly_bracket", "o")
        await pilot.press("i", "ctrl+a", "ctrl+k", *"0.35", "enter")
        await pilot.pause()
    assert engine.commands == [c.NudgeMean(1, 0.01), c.NudgeMean(2, -0.01),
                             c.SetParams({"REFERENCE ONE.On": True}),
                             c.SetParams({"REFERENCE ONE.Mean": 0.35})]


async def test_plot_type_window_sets_the_trend(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("g", "6")  # y1 y2 ref1 ref2: the other trend's, not offered
        assert app.screen is not app.main
        await pilot.press("7")
        await pilot.pause()
        app.main.refresh_view()
        assert app.main.query_one("#upper", Trend).plot_type == "y1 y2 y3 y4"


async def test_logging_window_logon_and_save_asks_before_overwriting(engine: Recording) -> None:
    (engine.logs_dir / "data.log").write_text("% an earlier log\n")
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("r", "l")
        await pilot.press("ctrl+a", "ctrl+k", *"600", "ctrl+o")
        await pilot.pause()
        assert engine.snapshot().params.logging.points == 600 and engine.snapshot().log.active
        engine.run_for(60.0)
        await pilot.press("ctrl+b", "ctrl+s")
        await pilot.pause()
        assert isinstance(app.screen, ConfirmWindow)
        await pilot.press("y")
        await pilot.pause()
    assert engine.sent(c.LogSave) == [c.LogSave("data", overwrite=True)]
    assert not engine.snapshot().log.unsaved


@pytest.mark.parametrize("to_second", [("tab",), ("right", "right", "left")], ids=["tab", "arrows"])
async def test_exit_asks_and_discards_an_unsaved_log(engine: Recording, to_second: tuple[str, ...]) -> None:
    """The second answer, Discard, reached by Tab or by the arrows (over SSH a user
    reaches for the arrows in a dialog: before, they did nothing, and Enter then
    took the first answer)."""
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        for command in (c.SetState("Run"), c.LogOn()):
            engine.submit(command)
        engine.run_for(5.0)
        await pilot.press("q")
        assert isinstance(app.screen, ChoiceWindow)
        await pilot.press("escape")
        assert app.screen is app.main and not engine.sent(c.LogDiscard)
        await pilot.press("ctrl+q", *to_second)
        assert app.screen.focused is not None and app.screen.focused.id == "choice-1"
        await pilot.press("enter")
        await pilot.pause()
    assert engine.sent(c.LogDiscard) == [c.LogDiscard()]
    assert app.return_code == 0


async def test_command_palette_lists_the_screen_actions(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)):
        titles = {cmd.title for cmd in app.get_system_commands(app.main)}
    assert {"Run", "Pause", "Manual", "Auto", "Log", "Exit", "Element 11", "Tanks"} <= titles
    assert "Element 12" not in titles


async def test_speed_keys_step_1_2_5_in_virtual_simul(make_engine, engine: Recording) -> None:
    assert make_app(engine).main.check_action("speed", (1,)) is None  # manual: unpaced
    engine = make_engine(clock="virtual", speed=1.0)
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("minus", *["plus"] * 11, "minus", "minus")
        await pilot.pause()
    assert [cmd.factor for cmd in engine.sent(c.SetSpeed)] == [
        2, 5, 10, 20, 50, 100, 200, 500, 1000, 500, 200]  # the ends do not move


async def test_modified_values_are_marked_and_default_restores(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("1", "ctrl+a", "ctrl+k", *"5.5", "enter")
        await pilot.pause()
        await pilot.press("1")
        window = app.screen
        assert isinstance(window, PIDWindow)
        assert window.query_one("#row-0").has_class("-modified")       # K
        assert not window.query_one("#row-1").has_class("-modified")   # Ti
        await pilot.press("ctrl+r")
        assert window.field_widget("CONTROLLER ONE.K").value == "3"
        assert not window.query_one("#row-0").has_class("-modified")
        await pilot.press("enter")
        await pilot.pause()
    assert engine.snapshot().params.get("CONTROLLER ONE.K") == 3.0


async def test_mouse_on_modes_trend_and_input_panel(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        status = app.main.query_one("#status")
        line = str(status.render()).splitlines()[0]
        await pilot.click("#status", offset=(line.index("Run") + 1, 0))
        await pilot.pause()
        await pilot.click("#lower")
        assert isinstance(app.screen, PlotTypeWindow) and app.screen.key == "PLOTS.Lower"
        await pilot.press("escape")
        await pilot.click("#channel-2")
        assert isinstance(app.screen, InputSignalWindow)
        await pilot.press("escape")
    assert engine.commands == [c.SetState("Run")]


async def test_logging_window_warns_when_the_file_exists(engine: Recording) -> None:
    (engine.logs_dir / "data.log").write_text("% an earlier log\n")
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("l")
        assert "exists" in str(app.screen.query_one("#file-error").render())
        await pilot.press("tab", "ctrl+a", "ctrl+k", *"fresh")
        assert str(app.screen.query_one("#file-error").render()).strip() == ""
