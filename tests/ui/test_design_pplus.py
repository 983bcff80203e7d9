"""At P+ the Design screen proposes what `quadtank design --par params/nonminphase.par`
gives (loop 2 with loop 1 closed, a stable pair), and its preview finds the same
settling as the command's, to the second."""

from __future__ import annotations

import json
from pathlib import Path

from textual.widgets import Static

from quadtank_tui.cli import main
from quadtank_tui.files.par import read_par
from quadtank_tui.ui.screens.design import DesignScreen
from quadtank_tui.ui.widgets.candidates_table import CandidatesTable
from quadtank_tui.ui.windows.design_preview import DesignPreviewWindow

from uikit import make_app, workers_done  # noqa: E402

PPLUS = Path(__file__).resolve().parents[2] / "params" / "nonminphase.par"


async def _settle(pilot) -> None:
    await pilot.pause()
    await workers_done(pilot.app)
    await pilot.pause()


async def test_p_plus_screen_proposes_the_clis_stable_pair_and_its_preview(make_engine, capsys, monkeypatch) -> None:
    """(The robustness spread is tested in the core: tests/core/design/test_robust.py.)"""
    import quadtank_tui.app.design as use_case

    def no_spread(*args: object, **kwargs: object) -> None:
        raise ValueError("not in this test")

    monkeypatch.setattr(use_case, "robustness_of", no_spread)
    assert main(["design", "--par", str(PPLUS), "--json", "--spread", "0"]) == 0
    cli = json.loads(capsys.readouterr().out)
    app = make_app(make_engine(read_par(PPLUS).params))
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        await pilot.press("d")
        await _settle(pilot)
        screen = pilot.app.screen
        assert isinstance(screen, DesignScreen)
        chosen = [screen.loops[i].chosen for i in (1, 2)]
        assert [(c.Kc, c.Ti) for c in chosen if c] == [(d["Kc"], d["Ti"]) for d in cli["loops"]]
        assert "closed loop stable" in str(screen.query_one("#design-mimo", Static).render())
        await pilot.press("l")  # loop 2: on what it sees with loop 1 closed, its default suggested
        await _settle(pilot)
        state = screen.loops[2]
        assert state.how == "g22 with loop 1 closed" and state.best is not None
        table = screen.query_one(CandidatesTable)
        assert str(table.get_row_at(state.best)[0]) == "PI Ms 1.4"
        assert str(table.get_row_at(state.best)[-1]) == "best"
        await pilot.press("A")
        await pilot.pause()
        window = pilot.app.screen
        assert isinstance(window, DesignPreviewWindow)
        await _settle(pilot)
        assert window.result is not None
    tui = [s.sim.settling for s in window.result.steps]
    assert tui == [s["simulated"]["settling_time"] for s in cli["preview"]["steps"]]
    assert tui[1] is not None and round(tui[1]) == 1064 and not window.result.warnings  # it settles: nothing to confirm
