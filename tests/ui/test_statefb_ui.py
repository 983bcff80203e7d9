"""The state feedback in the TUI: Type window row, Controller box, its window."""

from __future__ import annotations

import dataclasses
from typing import Any, Callable

import pytest
from textual.widgets import Input
from uikit import Recording, make_app

from quadtank_tui.core.parameters import PLANT_SETTINGS, PRESET, Parameters
from quadtank_tui.core.plants.spec import PlantSpec
from quadtank_tui.engine.commands import ResetControllers, SetParams
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
        assert isinstance(app.screen, StateFeedbackWindow)
        poles = app.screen.field_widget("STATE FEEDBACK.Poles")
        assert isinstance(poles, Input)
        poles.value = "-0.1+0.2j"
        await pilot.press("enter")
        await pilot.pause()
        assert isinstance(app.screen, StateFeedbackWindow)
        assert "conjugate" in str(app.screen.query_one("#e-1").render())
        before = len(engine.commands)  # Reset: the integrators, nothing else; the window closes
        await pilot.click("#reset_integrators")
        await pilot.pause()
        assert engine.commands[before:] == [ResetControllers()] and not isinstance(app.screen, StateFeedbackWindow)


# --- the coupled tanks (issue 15 item 3) -------------------------------------------------

def _coupled(name: str, levels: tuple[float, float] | None = None) -> Parameters:
    """A shipped plant setting with the state feedback chosen (the two-input rig at
    levels its pumps can hold: Murray-Smith's (0.115, 0.071) m needs pump 2 < 0)."""
    p = PLANT_SETTINGS[name].with_values({"CONTROL.Type": "State feedback", "STATE FEEDBACK.Ts": 20.0})
    if levels is not None:
        assert p.process is not None
        p = dataclasses.replace(p, process=PlantSpec.of(p.process.plant(), levels))
    return p


CASCADE_SF = _coupled("coupled-cascade")
TITO_SF = _coupled("coupled-tito", (0.15, 0.10))
QTP_SF = _coupled("desautel-qtp")


def test_main_with_state_feedback_on_the_cascade_120x40(snap_compare, make_engine: Callable[..., Recording]) -> None:
    assert snap_compare(make_app(make_engine(CASCADE_SF)), terminal_size=(120, 40))


def test_main_with_state_feedback_on_the_two_input_rig_120x40(
        snap_compare, make_engine: Callable[..., Recording]) -> None:
    assert snap_compare(make_app(make_engine(TITO_SF)), terminal_size=(120, 40))


def test_main_with_state_feedback_on_desautels_qtp_120x40(snap_compare, make_engine: Callable[..., Recording]) -> None:
    assert snap_compare(make_app(make_engine(QTP_SF)), terminal_size=(120, 40))


def test_state_feedback_window_on_the_cascade(snap_compare, make_engine: Callable[..., Recording]) -> None:
    assert snap_compare(make_app(make_engine(CASCADE_SF)), terminal_size=(80, 24), press=["1"])


def test_state_feedback_window_on_the_two_input_rig(snap_compare, make_engine: Callable[..., Recording]) -> None:
    assert snap_compare(make_app(make_engine(TITO_SF)), terminal_size=(80, 24), press=["1"])


@pytest.mark.parametrize("params, gains", [(CASCADE_SF, ("2.12 9.98", "0.132")), (TITO_SF, None), (QTP_SF, None)])
async def test_the_box_shows_the_coupled_tanks_design(make_engine: Any, params: Parameters,
                                                        gains: tuple[str, str] | None) -> None:
    """Desautel's CTP at Ts 20 s: L1 = [2.1179 9.9757], L2 = 0.13191 in the box; the
    two-input rig and the QTP: two rows of each, 4 or 6 poles (two pairs shown once)."""
    engine = make_engine(params)
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        info = engine.snapshot().statefb
        assert info is not None and engine.snapshot().fault is None
        text = str(app.main.query_one(StateFeedbackCell).render())
        assert f"δ {info.delta:.3f}" in text
        if gains is not None:
            assert f"L1 {gains[0]}" in text and f"L2 {gains[1]}" in text, text
            assert "0.9753" in text and "0.9802±0.0185i" in text, text
        else:
            n = len(params.process_levels()) + 2  # the levels and two integrators
            assert len(info.L1) == len(info.L2) == 2 and len(info.poles_z) == n
            assert text.count("±") == 2, text
        await pilot.press("1")
        await pilot.pause()
        assert isinstance(app.screen, StateFeedbackWindow)
        assert app.screen.field_widget("STATE FEEDBACK.Level1").disabled
