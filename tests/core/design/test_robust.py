"""The robustness spread: plants drawn about the nominal one, each started at its own
steady state, run on the batch path; the nominal plant's figures are the preview's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from quadtank_tui.app.design import design_pair, preview_plan, robustness_of
from quadtank_tui.core.design.pid_tuning import PIDTuning
from quadtank_tui.core.design.mimo import model_in_use
from quadtank_tui.core.design.robust import Spread, draw_plants, format_robustness, robustness, steady_state
from quadtank_tui.core.plants.johansson import steady_state_levels
from quadtank_tui.files.par import read_par

PARAMS = Path(__file__).resolve().parents[3] / "params"


def test_drawn_plants_stay_in_the_stated_spread_and_start_at_rest() -> None:
    nominal = read_par(PARAMS / "minphase.par").params.quadtank_constants()
    plants = draw_plants(nominal, 200, Spread(0.1, 0.1, 0.05), seed=3)
    assert plants[0] == nominal
    a1 = np.array([p.a1 for p in plants]) / nominal.a1
    g2 = np.array([p.gamma2 for p in plants]) - nominal.gamma2
    assert 0.9 <= a1.min() < 0.92 and 1.08 < a1.max() <= 1.1  # uniform over the whole +-10 %
    assert -0.05 <= g2.min() < -0.04 and 0.04 < g2.max() <= 0.05
    for p in plants[:20]:
        start = steady_state(p, 12.4, 12.7)
        assert start is not None
        x, v = start
        # the inverse, by johansson's own steady state of those pump volts
        assert steady_state_levels((v[0], v[1]), p) == pytest.approx(x, rel=1e-6)


def test_the_nominal_plant_of_the_spread_gives_the_previews_figures() -> None:
    """P-: the batch path (RK4, vectorized) and the preview (the engine's integrator,
    sample by sample) on the same plant and pair: the same step, and 100 plants in one run."""
    params = read_par(PARAMS / "minphase.par").params
    G, h = model_in_use(params), params.tsamp
    plan = preview_plan(params, design_pair(G, h).pid_pair(), None, h)
    pv = plan.run()
    rb = robustness_of(params, plan, pv, n=100)
    assert rb.n == rb.held == 100 and not rb.warnings
    for s, spread in zip(pv.steps, rb.steps):
        assert spread.overshoot[0] == pytest.approx(s.sim.overshoot_pct, abs=0.05)
        assert spread.settling[0] == pytest.approx(s.sim.settling, abs=h + 1e-9)
        # the IAE over its own (shorter or longer) window: the band's tail differs by < 1 %
        assert spread.iae[0] == pytest.approx(s.sim.iae, rel=0.01)
        assert np.median(spread.settling) < np.max(spread.settling)  # the plants differ
    assert "r1: overshoot 0.0 / 0.0 %" in format_robustness(rb)


def test_a_pair_unstable_on_the_nominal_plant_is_said_over_the_spread() -> None:
    """P+ with a positive PI on loop 2 (the pair is unstable at P+: lambda11(0) < 0)."""
    params = read_par(PARAMS / "nonminphase.par").params
    plants = draw_plants(params.quadtank_constants(), 40)
    lv = params.operating_levels()
    rb = robustness(plants, (lv[0], lv[1]), (PIDTuning(3.0, 63.0), PIDTuning(1.5, 90.0)), 2.0, 1500.0)
    assert rb.steps[1].unstable.sum() > 20
    assert any("go unstable" in w for w in rb.warnings)
