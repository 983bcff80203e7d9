"""The 2x2 check on the quadruple tank's physical linearization (P- and P+)."""

from __future__ import annotations

import numpy as np
import pytest

from quadtank_tui.core.design.pid_tuning import PIDTuning, DesignError
from quadtank_tui.core.design.mimo import (
    closed_loop_poles, design_2x2, design_loop, format_check, lambda11,
    loop2_with_loop1_closed, physical_model,
)
from quadtank_tui.core.plants.johansson import P_MINUS, P_PLUS


@pytest.fixture(scope="module")
def g_minus():
    return physical_model(P_MINUS.params, P_MINUS.op.x)


@pytest.fixture(scope="module")
def g_plus():
    return physical_model(P_PLUS.params, P_PLUS.op.x)


def test_rga_at_zero_matches_the_analysis(g_minus, g_plus) -> None:
    # lambda11(0) = 1/(1 - g12 g21/(g11 g22)); P-: 1.40 (Johansson & Nunes: 1.4), P+: -0.64
    assert lambda11(g_minus, 0.0).real == pytest.approx(1.400, abs=0.005)
    assert lambda11(g_plus, 0.0).real == pytest.approx(-0.636, abs=0.005)


def test_closed_loop_poles_judge_the_thesis_controllers(g_minus, g_plus) -> None:
    """The thesis's pairs are stable; at P+ two positive PIs are not (det G(0) < 0)."""
    assert closed_loop_poles(g_minus, PIDTuning(3.0, 30.0), PIDTuning(2.7, 40.0)).real.max() < 0
    assert closed_loop_poles(g_plus, PIDTuning(1.5, 110.0), PIDTuning(-0.12, 220.0)).real.max() < 0
    assert closed_loop_poles(g_plus, PIDTuning(1.5, 110.0), PIDTuning(0.12, 220.0)).real.max() > 0


def test_p_minus_design_is_stable_with_positive_gains(g_minus) -> None:
    chk = design_2x2(g_minus)
    c1, c2 = chk.pid_pair()
    assert chk.stable and c1.Kc > 0 and c2.Kc > 0 and not chk.notes
    assert chk.det_G0 > 0
    # lambda = T/5 on first-order elements: Kc = 5/K, Ti = T
    assert c1.Ti == pytest.approx(62.70, abs=0.01) and c1.Kc == pytest.approx(5 / 2.610, rel=1e-3)


def test_p_plus_reports_and_designs_k2_negative(g_plus) -> None:
    chk = design_2x2(g_plus)
    c1, c2 = chk.pid_pair()
    assert chk.det_G0 < 0 and chk.lambda11_0 < 0
    assert "no decentralized PI with the signs of the diagonal gains (both positive) stabilizes" in chk.notes[0]
    assert c1.Kc > 0 and c2.Kc < 0 and chk.stable
    assert chk.loops[1].how == "g22 with loop 1 closed"
    assert chk.loops[1].evaluation.Ms == pytest.approx(1.4, abs=0.01)
    # the effective loop-2 plant has det G(0)/g11(0) as gain and the RHP zero of P+
    g2 = chk.loops[1].model
    assert g2.static_gain == pytest.approx(chk.det_G0 / g_plus[0][0].static_gain, rel=1e-4)
    rhp = [z for z in g2.zeros() if z.real > 0]
    assert len(rhp) == 1 and 0 < rhp[0].real < 0.013
    # its zeros are those of g22 + c1 det G: with a tight loop 1, P+'s zero +0.013
    tight = loop2_with_loop1_closed(g_plus, PIDTuning(1e4, 63.2))
    assert [round(z.real, 4) for z in tight.zeros() if z.real > 0] == [0.0128]
    text = format_check(chk)
    assert "closed loop stable" in text and "K2 = -" in text


def test_sequential_model_is_g22_when_loops_do_not_interact(g_minus) -> None:
    zero = type(g_minus[0][1])((0.0,), (1.0,))
    G = ((g_minus[0][0], zero), (zero, g_minus[1][1]))
    eff = loop2_with_loop1_closed(G, PIDTuning(1.0, 60.0))
    w = np.logspace(-3, 0, 20)
    np.testing.assert_allclose(eff.freqresp(w), g_minus[1][1].freqresp(w), rtol=1e-9)


def test_ms_alone_does_not_bound_a_delay_free_first_order_loop(g_minus) -> None:
    with pytest.raises(DesignError, match="Ms alone does not bound"):
        design_loop(g_minus[0][0], "pi-ms")
    with pytest.raises(DesignError, match="unknown method"):
        design_loop(g_minus[0][0], "zn")
