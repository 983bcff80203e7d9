"""The batch simulator of the physical fit (core.identify.fastsim) against each
plant's own adaptive step, with every real-rig effect on: the fit searches with one
and reports from the other, so they must agree."""

from __future__ import annotations

import numpy as np
import pytest

from quadtank_tui.core.identify import fastsim
from quadtank_tui.core.identify.physical import simulate
from quadtank_tui.core.plants import CoupledCascade, DesautelQTP, QuadTank
from quadtank_tui.core.plants.johansson import P_MINUS

RIGS = {
    "quadtank": (QuadTank(P_MINUS.params, lam1=0.1, lam2=0.08, lam3=0.09, lam4=0.07, vmin1=0.35, vmin2=0.45,
                          off1=0.06, off2=-0.04, ysat1=7.0), 1.0),
    "desautel-qtp": (DesautelQTP(lam1=0.002, lam4=0.001, vmin2=0.5, off3=0.1), 2.0),
    "coupled-cascade": (CoupledCascade(lam1=0.004, lam2=0.003, area1=2.0, vmin=0.5, off2=0.2, ysat2=4.0), 4.0),
}


@pytest.mark.parametrize("kind", sorted(RIGS))
def test_batch_simulation_is_the_plants_own_within_its_tolerance(kind: str) -> None:
    rig, h = RIGS[kind]
    m = len(rig.inputs)
    rng = np.random.default_rng(3)
    base = np.array([3.0, 3.0][:m]) if kind != "coupled-cascade" else np.array([8.0])
    u = np.repeat(base * (1 + 0.25 * rng.choice([-1.0, 1.0], size=(8, m))), 10, axis=0)
    x0 = rig.steady_state(tuple(u[0]))
    x = simulate(rig, x0, u, h)
    y = np.array([rig.output(r) for r in x])
    b = fastsim.batch(kind, rig.values(), 3)
    xb = fastsim.simulate(b, np.tile(x0, (3, 1)), u, h)
    yb = fastsim.sensors(b, xb)
    scale = max(s.hi for s in rig.states)
    assert np.abs(xb - x[:, None, :]).max() < 1e-5 * scale
    assert np.abs(yb - y[:, None, :]).max() < 1e-5 * scale
    assert fastsim.steady(b, u[0])[0] == pytest.approx(x0, rel=1e-9)


def test_a_still_output_with_a_noisy_sensor_gets_no_fit_percent() -> None:
    from quadtank_tui.core.identify.crossval import figure

    rng = np.random.default_rng(5)
    still = 0.3 + 0.0005 * rng.standard_normal(600)           # a tank that does not move, 5 mV of noise
    moving = 0.3 + 0.05 * np.sin(np.arange(600) / 40) + 0.0005 * rng.standard_normal(600)
    f = figure("a.log", "y3", still, np.full(600, 0.3), 10.0, 0.5, "cm")
    assert f.fit_percent != f.fit_percent and f.unit == "cm"  # NaN: n/a, not a negative fit
    g = figure("a.log", "y1", moving, moving - 0.001, 10.0, 0.5, "cm")
    assert 95.0 < g.fit_percent < 100.0
