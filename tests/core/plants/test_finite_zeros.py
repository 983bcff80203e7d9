"""Transmission zeros: the finite ones only, whatever the machine's rounding does
with the Rosenbrock pencil's infinite eigenvalues (found when the n4sid model of the
shipped P- experiment was called nonminimum phase on an AVX-512 machine: a zero at
+3.3e14 s^-1 that python-control's zeros() kept)."""

from __future__ import annotations

import numpy as np
import pytest

from quadtank_tui.core.analysis import linearize, zeros_from_valves
from quadtank_tui.core.identify.system import from_state_space
from quadtank_tui.core.plants.johansson import P_MINUS, P_PLUS
from quadtank_tui.core.plants.linear import finite_zeros

A = np.diag([-0.016, -0.011, -0.04, -0.025])  # s^-1: the quadruple tank's time scale
B = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 0.0], [0.0, 1.0]])


def _c(eps: float) -> np.ndarray:
    """G = [[1/(s+a), 1/(s+b)], [1/(s+c), (1+eps)/(s+d)]]: det G's numerator is
    eps s^2 + (0.01 + 0.051 eps) s + 4e-5 + 4.4e-4 eps, a zero near -0.004 s^-1 and
    one near -0.01/eps."""
    return np.array([[1.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 1.0 + eps]])


def test_the_two_settings_zeros_are_the_papers() -> None:
    """P- has two zeros in the left half-plane, P+ one in the right (Johansson's
    process, Nunes 2.2), where the paper's closed form puts them; the identified-model
    path gives the same zeros."""
    for setting, rhp in ((P_MINUS, 0), (P_PLUS, 1)):
        m = linearize(setting.params, setting.op.x)
        z = finite_zeros(m.A, m.B, m.C, m.D)
        assert len(z) == 2 and sum(z.real > 0) == rhp
        assert z.real == pytest.approx(zeros_from_valves(setting.params, setting.op.x), rel=1e-9)
        assert np.array(from_state_space(m.A, m.B, m.C).zeros) == pytest.approx(z, rel=1e-12)


@pytest.mark.parametrize("eps", [1e-13, -1e-13, 1e-15, -1e-15])
def test_a_zero_at_infinity_left_finite_by_rounding_is_dropped(eps: float) -> None:
    """C B nearly singular: the pencil has a third eigenvalue near 1/eps, of either
    sign, which no sampled response can see.  Kept, its sign decided the phase."""
    C = _c(eps)
    z = finite_zeros(A, B, C, np.zeros((2, 2)))
    assert z == pytest.approx([-0.004], rel=1e-3)
    model = from_state_space(A, B, C)
    assert model.zeros == pytest.approx(tuple(z)) and model.phase == "minimum"


def test_a_zero_far_out_but_within_reach_is_kept() -> None:
    """A zero a thousand times faster than the fastest pole is a zero (it shapes the
    response in the first sample): only those beyond 1e8 times go."""
    z = finite_zeros(A, B, _c(1e-3), np.zeros((2, 2)))
    assert z == pytest.approx(np.sort(np.roots([1e-3, 0.01 + 0.051e-3, 4e-5 + 4.4e-4 * 1e-3])), rel=1e-9)
    assert z[0] == pytest.approx(-10.0, rel=0.01)


@pytest.mark.parametrize("lead", [1e-11, -1e-11])
def test_an_elements_zero_at_infinity_is_not_a_zero(lead: float) -> None:
    """An element of relative degree 2 whose numerator kept a leading coefficient of
    rounding: its far root goes (either sign), the real zero stays."""
    from quadtank_tui.core.delaytf import DelayTF
    from quadtank_tui.core.identify.system import element_zeros

    g = DelayTF((lead, 0.02, 0.0004), (1.0, 0.06, 0.0008, 0.0), 0.0)  # zero at -0.02, poles to 0.04
    assert len(g.zeros()) == 2 and np.abs(g.zeros()).max() > 1e8
    assert element_zeros(g) == pytest.approx([-0.02])
    assert element_zeros(DelayTF((0.02, 0.0004), (1.0, 0.06, 0.0008), 0.0)) == pytest.approx([-0.02])


@pytest.mark.parametrize("slow", [0.0, 1e-8])
def test_a_model_of_integrators_keeps_its_zeros(slow: float) -> None:
    """Poles at 0 (or at rounding's 1e-8): the bound is taken from a pole of 1e-4 s^-1
    at least, so (s + 10) / s^2 keeps its zero at -10 s^-1, and (s + 1) / s its -1."""
    from quadtank_tui.core.delaytf import DelayTF
    from quadtank_tui.core.identify.system import element_zeros

    A = np.array([[-slow, 1.0], [0.0, -slow]])
    z = finite_zeros(A, np.array([[0.0], [1.0]]), np.array([[10.0, 1.0]]), np.zeros((1, 1)))
    assert z == pytest.approx([-10.0 + slow * 0])
    assert element_zeros(DelayTF((1.0, 1.0), (1.0, slow), 0.0)) == pytest.approx([-1.0])


@pytest.mark.parametrize("eps, degree", [(1e-11, 0), (-1e-11, 0), (1e-3, 1)])
def test_a_fitted_elements_numerator_loses_a_leading_coefficient_of_rounding(eps: float, degree: int) -> None:
    """y = x2 + eps x1 behind two lags: G = (eps (s + 0.02) + 1) / ((s + 0.05)(s + 0.02)),
    a zero near -1/eps.  At eps = +-1e-11 (rounding's C B) the numerator is the
    constant it should be, its static gain kept; at 1e-3 the zero (-1000) stays."""
    A = np.array([[-0.05, 0.0], [1.0, -0.02]])
    B = np.array([[1.0], [0.0]])
    C = np.array([[eps, 1.0]])
    (g,), = from_state_space(A, B, C).elements
    assert g is not None and len(g.num) - 1 == degree
    assert g.static_gain == pytest.approx((eps * 0.02 + 1) / (0.05 * 0.02), rel=1e-12)
    if degree:
        assert g.zeros() == pytest.approx([-(0.02 * eps + 1) / eps], rel=1e-9)
