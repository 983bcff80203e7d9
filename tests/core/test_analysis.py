"""Linearization against the published figures (Nunes 2.2; Johansson & Nunes 2).

Two kinds of assertion, as issue 2 asks:
- against the *printed* figures, with the tolerance that rounding of the printed
  inputs explains (T within 1 s, G(0) within 0.07, zeros within 0.003);
- against our own exact computation (closed-form formulas written out here), tightly.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from quadtank_tui.core.analysis import analyze, linearize, zeros_from_valves
from quadtank_tui.core.plants.johansson import P_MINUS, P_PLUS, steady_state_levels

PUBLISHED = {
    "minphase": {
        "T": (62, 90, 23, 30),
        "G0": ((2.6, 1.5), (1.4, 2.8)),
        "zeros": (-0.060, -0.018),
        "phase": "minimum",
    },
    "nonminphase": {
        "T": (63, 91, 39, 56),
        "G0": ((1.5, 2.5), (2.5, 1.6)),
        "zeros": (-0.057, 0.013),
        "phase": "nonminimum",
    },
}
SETTINGS = {"minphase": P_MINUS, "nonminphase": P_PLUS}


@pytest.mark.parametrize("name", ["minphase", "nonminphase"])
def test_published_figures_within_rounding(name: str) -> None:
    s, pub = SETTINGS[name], PUBLISHED[name]
    r = analyze(s.params, s.op.x)
    assert r.time_constants == pytest.approx(pub["T"], abs=1.0)
    assert r.static_gains == pytest.approx(np.array(pub["G0"]), abs=0.07)
    assert sorted(z.real for z in r.zeros) == pytest.approx(sorted(pub["zeros"]), abs=0.003)
    assert all(z.imag == 0 for z in r.zeros)
    assert r.phase == pub["phase"]


def test_minphase_exact_values_at_table_levels() -> None:
    """control.md: at the table's levels T = (62.70, 90.34, 23.89, 29.99), zeros -0.0580, -0.0172."""
    r = analyze(P_MINUS.params, P_MINUS.op.x)
    assert r.time_constants == pytest.approx((62.7034, 90.3353, 23.8900, 29.9930), abs=1e-4)
    assert sorted(z.real for z in r.zeros) == pytest.approx((-0.0580175, -0.0171821), abs=1e-7)
    assert r.static_gains == pytest.approx(np.array([[2.610029, 1.500403], [1.410078, 2.837093]]), abs=1e-6)


def test_minphase_exact_values_at_steady_state_of_table_voltages() -> None:
    """control.md: levels 12.26/12.78/1.63/1.41 give T = (62.36, 90.63, 22.76, 30.09),
    zeros -0.0597, -0.0175 - closer to the printed figures."""
    h = steady_state_levels(P_MINUS.op.u, P_MINUS.params)
    r = analyze(P_MINUS.params, h)
    assert r.time_constants == pytest.approx((62.36, 90.63, 22.76, 30.09), abs=0.005)
    assert sorted(z.real for z in r.zeros) == pytest.approx((-0.0597, -0.0175), abs=5e-5)


@pytest.mark.parametrize("setting", [P_MINUS, P_PLUS])
def test_against_closed_form(setting) -> None:
    """G(0), T_i and zeros from the thesis's formulas, written out independently."""
    p, h = setting.params, setting.op.x
    A, a = (p.A1, p.A2, p.A3, p.A4), (p.a1, p.a2, p.a3, p.a4)
    T = [A[i] / a[i] * math.sqrt(2 * h[i] / p.g) for i in range(4)]
    c1, c2 = T[0] * p.kc / p.A1, T[1] * p.kc / p.A2
    G0 = np.array([
        [p.gamma1 * p.k1 * c1, (1 - p.gamma2) * p.k2 * c1],
        [(1 - p.gamma1) * p.k1 * c2, p.gamma2 * p.k2 * c2],
    ])
    r = analyze(p, h)
    assert r.time_constants == pytest.approx(T, rel=1e-12)
    assert r.static_gains == pytest.approx(G0, rel=1e-12)
    assert sorted(z.real for z in r.zeros) == pytest.approx(zeros_from_valves(p, h), rel=1e-8)
    # G(0) equals the state-space DC gain -C A^-1 B
    m = linearize(p, h)
    assert -m.C @ np.linalg.solve(m.A, m.B) == pytest.approx(G0, rel=1e-10)
    # RGA lambda11 = gamma1 gamma2 / (gamma1 + gamma2 - 1) (the k's and c's cancel)
    lam = p.gamma1 * p.gamma2 / (p.gamma1 + p.gamma2 - 1)
    assert r.rga == pytest.approx(np.array([[lam, 1 - lam], [1 - lam, lam]]), rel=1e-10)


def test_paper_swaps_k1_k2_in_off_diagonal_gains() -> None:
    """The printed P+ G(0) (2.5, 2.5 off-diagonal) is matched better by the physics
    (G12 with k2, G21 with k1) than by the paper's printed formula (swapped)."""
    p, h = P_PLUS.params, P_PLUS.op.x
    r = analyze(p, h)
    T1, T2 = r.time_constants[:2]
    c1, c2 = T1 * p.kc / p.A1, T2 * p.kc / p.A2
    swapped = ((1 - p.gamma2) * p.k1 * c1, (1 - p.gamma1) * p.k2 * c2)
    physics = (r.static_gains[0, 1], r.static_gains[1, 0])
    assert abs(physics[0] - 2.5) + abs(physics[1] - 2.5) < abs(swapped[0] - 2.5) + abs(swapped[1] - 2.5)


def test_rga_undefined_when_valves_sum_to_one() -> None:
    p = P_MINUS.params.with_valves(0.5, 0.5)
    r = analyze(p, P_MINUS.op.x)
    assert r.rga is None
    assert r.phase == "nonminimum"
    assert min(abs(z) for z in r.zeros) < 1e-9  # a zero at the origin


def test_bad_operating_point_is_refused() -> None:
    with pytest.raises(ValueError, match="h3"):
        linearize(P_MINUS.params, (12.0, 12.0, 0.0, 1.0))


@pytest.mark.parametrize("gammas", [(0.7, 0.6), (0.43, 0.34), (0.9, 0.2), (0.15, 0.8), (0.5, 0.5)])
def test_pencil_zeros_equal_python_controls(gammas: tuple[float, float]) -> None:
    """transmission_zeros avoids importing python-control; it must still agree with it."""
    import control
    from dataclasses import replace

    from quadtank_tui.core.analysis import transmission_zeros

    p = replace(P_MINUS.params, gamma1=gammas[0], gamma2=gammas[1])
    m = linearize(p, P_MINUS.op.x)
    ours = np.sort_complex(np.array(transmission_zeros(m)))
    theirs = np.sort_complex(np.asarray(control.zeros(m.ss()), dtype=complex))
    assert len(ours) == len(theirs)
    assert ours == pytest.approx(theirs, rel=1e-9, abs=1e-12)


def test_one_linear_model_class_for_the_quadruple_tank_and_the_plant_family() -> None:
    """analysis.linearize gives core.plants.linear's LinearModel (issue 18 folded the
    two classes): the same matrices as the plant family's linearization, named
    signals, x0 the operating levels."""
    from quadtank_tui.core import analysis
    from quadtank_tui.core.plants.linear import LinearModel

    m = linearize(P_MINUS.params, P_MINUS.op.x)
    assert analysis.LinearModel is LinearModel and isinstance(m, LinearModel)
    assert (m.states, m.inputs, m.outputs) == (("h1", "h2", "h3", "h4"), ("v1", "v2"), ("y1", "y2"))
    assert m.x0 == tuple(P_MINUS.op.x)
    assert [-1.0 / m.A[i, i] for i in range(4)] == pytest.approx(analyze(P_MINUS.params, P_MINUS.op.x).time_constants,
                                                                 rel=1e-12)
