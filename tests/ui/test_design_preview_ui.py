"""The preview before Apply (issue 23): a pair that limit-cycles on the simulated
plant is applied only after a question that says so; Esc applies nothing."""

from __future__ import annotations

import pytest
from textual.widgets import Button, Static

from quadtank_tui.core.design.pid_tuning import PIDTuning
from quadtank_tui.core.parameters import PRESET
from quadtank_tui.ui.windows.base import ChoiceWindow
from quadtank_tui.app.design import PreviewPlan
from quadtank_tui.ui.windows.design_preview import DesignPreviewWindow

from uikit import make_app  # noqa: E402


@pytest.fixture
def app(engine):
    return make_app(engine)


def _request() -> PreviewPlan:
    """The issue's loop 1 (Kc 165.2, Ti 0.2753 s, designed in continuous time) at Ts = 1 s on P-."""
    plant = PRESET.process_plant()
    levels = PRESET.process_levels()
    op = plant.steady_inputs([levels[0], levels[1], None, None])
    return PreviewPlan(plant, tuple(op.x), tuple(op.u), (PIDTuning(165.2, 0.2753), PIDTuning(1.758, 90.34)), 1.0,
                       None, (1.0, 1.0), window=120.0)


async def _opened(pilot, answers: list):
    pilot.app.push_screen(DesignPreviewWindow(_request()), answers.append)
    await pilot.pause()
    await pilot.app.workers.wait_for_complete()
    await pilot.pause()
    return pilot.app.screen


async def test_a_limit_cycle_needs_a_confirmation_that_says_so(app) -> None:
    answers: list = []
    async with app.run_test(size=(120, 40)) as pilot:
        window = await _opened(pilot, answers)
        assert isinstance(window, DesignPreviewWindow) and window.result is not None
        assert "loop 1: the simulated plant limit-cycles" in str(window.query_one("#message", Static).render())
        assert str(window.query_one("#apply", Button).label) == "Apply anyway..."
        await pilot.press("enter")
        await pilot.pause()
        question = pilot.app.screen
        assert isinstance(question, ChoiceWindow) and "limit-cycles" in question.question
        await pilot.press("enter")  # the first answer: do not apply
        await pilot.pause()
        assert pilot.app.screen is window and answers == []
        await pilot.press("enter", "tab", "enter")  # Apply anyway: the second answer
        await pilot.pause()
        assert answers == [True]


async def test_escape_applies_nothing(app) -> None:
    answers: list = []
    async with app.run_test(size=(120, 40)) as pilot:
        await _opened(pilot, answers)
        await pilot.press("escape")
        await pilot.pause()
        assert answers == [None]
