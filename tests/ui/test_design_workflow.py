"""The lab's workflow through the TUI, by keys (issue 23): an identification
experiment's logs, `y` and a fit, `d`, the suggested row of each loop, `A` and the
preview on the simulated plant, Apply, a reference step on Main; what the plant
then did agrees with the preview.  And a row the table flags: the preview warns,
Apply asks, and No or Esc leave the matrix as it was.

The engine is the simulator on a manual clock (tests/ui/conftest.py): the plant
moves only when the test runs it, so the step is as long as the preview's window
and no longer.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from textual.widgets import Input, Static

from quadtank_tui.core.design.preview import STEP
from quadtank_tui.core.design.sampled_eval import CHATTER_SHARE, reversals
from quadtank_tui.core.metrics import loop_metrics
from quadtank_tui.engine.commands import SetParams
from quadtank_tui.ui.screens.design import DesignScreen
from quadtank_tui.ui.screens.main import MainScreen
from quadtank_tui.ui.widgets.candidates_table import CandidatesTable
from quadtank_tui.ui.windows.base import ChoiceWindow
from quadtank_tui.ui.windows.design_preview import DesignPreviewWindow

from bursts import burst  # noqa: E402
from uikit import make_app, workers_done  # noqa: E402
import test_identify_screen  # noqa: E402
from test_identify_screen import fit_both, simo_logs  # noqa: E402

GAINS = ("CONTROLLER ONE.K", "CONTROLLER ONE.Ti", "CONTROLLER ONE.Td",
         "CONTROLLER FOUR.K", "CONTROLLER FOUR.Ti", "CONTROLLER FOUR.Td")


async def settle(pilot: Any) -> None:
    """Until every worker is done; an exclusive worker (the plots) that a newer one
    cancelled while we waited is not a failure."""
    await pilot.pause()
    await workers_done(pilot.app)
    await pilot.pause()


async def choose_suggested(pilot: Any, screen: DesignScreen) -> None:
    """Enter on each loop's table, which opens on its suggested row."""
    table = screen.query_one(CandidatesTable)
    for loop in (1, 2):
        if screen.loop != loop:
            await pilot.press("l")
            await settle(pilot)
        best = screen.loops[loop].best
        assert best is not None and table.cursor_row == best and str(table.get_row_at(best)[-1]) == "best"
        await pilot.press("enter")
        await pilot.pause()
        assert screen.loops[loop].chosen is not None


async def preview_of(pilot: Any) -> DesignPreviewWindow:
    await pilot.press("A")
    await pilot.pause()
    window = pilot.app.screen
    assert isinstance(window, DesignPreviewWindow)
    await settle(pilot)
    assert window.result is not None
    return window


@pytest.fixture
def app(setup_app, monkeypatch):
    """P- under a PRBS on u1, then on u2, logged at 1 s (600 samples each: enough
    for the fit, half the time), and the loop sampled at 1 s as the lab's
    identification scripts are (the issue's Ts)."""
    monkeypatch.setattr(test_identify_screen, "ROWS", 600)
    simo_logs(Path("logs"))
    setup_app.engine.submit(SetParams({"SAMPLING TIME.TSamp": 1000}))
    return setup_app


async def test_identify_design_preview_apply_step(app) -> None:
    engine = app.engine
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        await pilot.press("r")
        engine.run_for(1.0)
        await pilot.press("a")  # Automatic, references at the measured levels
        engine.run_for(1.0)
        await fit_both(pilot)  # y, both logs, f
        await pilot.press("d")
        await settle(pilot)
        screen = pilot.app.screen
        assert isinstance(screen, DesignScreen) and screen.source.startswith("the identified model")
        assert "sampled at 1 s" in str(screen.query_one(CandidatesTable).border_title)
        await choose_suggested(pilot, screen)
        window = await preview_of(pilot)
        pv = window.result
        assert pv is not None and pv.warnings == [], pv
        figures = str(window.query_one("#preview-figures", Static).render())
        assert "r1 simulated" in figures and "r2 predicted" in figures
        await pilot.press("enter")  # Apply (focused once the preview is done)
        await pilot.pause()
        assert pilot.app.screen is screen
        c1, c2 = screen.loops[1].chosen, screen.loops[2].chosen
        p = engine.snapshot().params
        assert (p.get("CONTROLLER ONE.K"), p.get("CONTROLLER FOUR.K")) == (c1.Kc, c2.Kc)
        await burst(pilot, "escape", "escape")  # Design -> Identify -> Main
        assert isinstance(pilot.app.screen, MainScreen)

        # the step on r1 the preview simulated, from where the plant is
        step = pv.steps[0]
        r0 = engine.snapshot().r[0]
        await burst(pilot, "i", *f"+{STEP:g}", "enter")
        assert isinstance(pilot.app.screen, MainScreen)
        engine.run_for(step.window)
        h = engine.history(step.window)
        t, y1, r1 = h["t"], h["y1"], h["ref1"]
        moved = np.flatnonzero(r1 > r0 + STEP / 2)
        assert moved.size, "the reference never stepped"
        k = int(moved[0])
        assert r1[k] == pytest.approx(r0 + STEP, abs=1e-9)
        lm = loop_metrics(t[k - 1:], y1[k - 1:], r1[k - 1:])
        sim = step.sim
        assert lm.settling_time is not None and sim.settling is not None
        assert abs(float(lm.overshoot or 0.0) - sim.overshoot_pct) <= 5.0
        assert lm.settling_time == pytest.approx(sim.settling, rel=0.2)
        assert lm.iae == pytest.approx(sim.iae, rel=0.2)
        u = np.column_stack([h["u1"][k:], h["u2"][k:]])
        assert u.min() >= 0.0 and u.max() <= 1.0
        assert reversals(u[:, 0], STEP) <= CHATTER_SHARE and reversals(u[:, 1], STEP) <= CHATTER_SHARE


async def test_a_flagged_row_needs_a_yes_and_no_or_esc_applies_nothing(engine) -> None:
    """A model typed with 1/500 of g11's gain (2.61 at P-): λ = T/5 gives Kc 962 at
    1 s, which the table flags (its 10 % step does not settle with the pumps
    limited) and which on the simulated plant flips the pump between its limits."""
    engine.submit(SetParams({"SAMPLING TIME.TSamp": 1000}))
    engine.commands.clear()
    app = make_app(engine)
    before = {k: engine.snapshot().params.get(k) for k in GAINS}
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        await pilot.press("d")
        await settle(pilot)
        screen = pilot.app.screen
        assert isinstance(screen, DesignScreen)
        box = screen.query_one("#model-1", Input)
        box.value = ""
        box.focus()
        await pilot.press(*"0.005/(62.7*s+1)", "enter")
        await settle(pilot)
        rows = screen.loops[1].rows
        assert rows[0].method == "lambda" and rows[0].controller is not None
        assert rows[0].controller.Kc == pytest.approx(62.7 / (0.005 * (62.7 / 5 + 0.5)))  # the hold: h/2
        assert rows[0].problem == "the reference step does not settle" and screen.loops[1].best is None
        table = screen.query_one(CandidatesTable)
        assert str(table.get_row_at(0)[-1]) == "settle?"
        table.focus()
        await pilot.press(*["up"] * table.cursor_row)
        await pilot.pause()
        status = str(screen.query_one("#design-status", Static).render())
        assert "λ 12.5 s: the reference step does not settle" in status
        await pilot.press("enter")
        await pilot.pause()
        assert screen.loops[1].chosen is not None and screen.loops[1].chosen.Kc == 961.7
        window = await preview_of(pilot)
        assert window.result is not None
        assert any(w.startswith("loop 1: the simulated plant limit-cycles") for w in window.result.warnings)
        for answer in ("escape", "enter"):  # Esc on the question, then its first answer: Do not apply
            await pilot.press("enter")  # "Apply anyway..."
            await pilot.pause()
            question = pilot.app.screen
            assert isinstance(question, ChoiceWindow) and "loop 1" in question.question
            await pilot.press(answer)
            await pilot.pause()
            assert pilot.app.screen is window
        await pilot.press("escape")  # out of the preview: nothing applied
        await pilot.pause()
        assert pilot.app.screen is screen
        engine.run_for(0.1)
    assert engine.sent(SetParams) == []
    assert {k: engine.snapshot().params.get(k) for k in GAINS} == before
