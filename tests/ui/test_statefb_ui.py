"""The state feedback in the TUI: Type window row, Controller box, its window."""

from __future__ import annotations

from typing import Any, Callable

from conftest import Recording, make_app

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.engine.commands import SetParams
from quadtank_tui.ui.widgets.controller_box import StateFeedbackCell
from quadtank_tui.ui.windows.statefb import StateFeedbackWindow

STATEFB = PRESET.with_values({"CONTROL.Type": "State feedback"})


def test_main_with_state_feedback_120x40(snap_compare, make_engine: Callable[..., Recording]) -> None:
    assert snap_compare(make_app(make_engine(STATEFB)), terminal_size=(120, 40))


def test_main_with_state_feedback_80x24(snap_compare, make_engine: Callable[..., Recording]) -> None:
    assert snap_compare(make_app(make_engine(STATEFB)), terminal_size=(80, 24))


def test_state_feedback_window(snap_compare, make_engine: Callable[..., Recording]) -> None:
    assert snap_compare(make_app(make_engine(STATEFB)), terminal_size=(80, 24), press=["1"])


async def test_choosing_the_type_shows_the_design_and_a_setting_redesigns(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("t", "5")
        await pilot.pause()
        assert engine.sent(SetParams)[-1].values == {"CONTROL.Type": "State feedback"}
        app.main.refresh_view()
        await pilot.pause()
        cell = app.main.query_one(StateFeedbackCell)
        text = str(cell.render())
        info = engine.snapshot().statefb
        assert cell.display and info is not None
        assert f"{info.L1[0][0]:.3g}" in text and f"{info.delta:.3f}" in text
        await pilot.press("1")
        await pilot.pause()
        assert isinstance(app.screen, StateFeedbackWindow)
        field = app.screen.field_widget("STATE FEEDBACK.Ts")
        field.value = "90"
        await pilot.press("enter")
        await pilot.pause()
        assert engine.sent(SetParams)[-1].values == {"STATE FEEDBACK.Ts": 90.0}
        app.main.refresh_view()
        await pilot.pause()
        assert engine.snapshot().statefb != info
        assert "Ts 90 s" in str(app.main.query_one(StateFeedbackCell).render())


async def test_a_design_the_engine_refuses_is_shown_next_to_the_field(make_engine: Any) -> None:
    engine = make_engine(STATEFB)
    app = make_app(engine)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("1")
        await pilot.pause()
        app.screen.field_widget("STATE FEEDBACK.Poles").value = "-0.1+0.2j"
        await pilot.press("enter")
        await pilot.pause()
        assert isinstance(app.screen, StateFeedbackWindow)
        assert "conjugate" in str(app.screen.query_one("#e-1").render())
