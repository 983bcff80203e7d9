"""General transfer-function element: Tustin against scipy, stepping, bumpless changes."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal
from hypothesis import given, settings, strategies as st

from quadtank_tui.core.controllers.general import General, GeneralParams, tustin
from quadtank_tui.core.ranges import ParameterError

# A PID with derivative filter written as a General element, degree 2:
# C(s) = K (1 + 1/(Ti s) + Td s/(1 + s Td/N)) with K=2, Ti=20, Td=5, N=10.
K, TI, TD, N = 2.0, 20.0, 5.0, 10.0
_num = np.polyadd(np.polymul([K * TI, K], [TD / N, 1.0]), [K * TI * TD, 0.0, 0.0])
_den = np.polymul([TI, 0.0], [TD / N, 1.0])
PIDF = GeneralParams(degree=2, s=(*(_num / _den[0]), 0.0, 0.0), r=(*(_den[1:] / _den[0]), 0.0, 0.0))
LEAD4 = GeneralParams(degree=4, s=(0.5, 3.0, 2.0, 0.7, 0.05), r=(2.0, 1.5, 0.5, 0.06))


@pytest.mark.filterwarnings("ignore::scipy.signal.BadCoefficients")  # s0 = 0: scipy trims it
@pytest.mark.parametrize("params", [GeneralParams(), PIDF, LEAD4,
                                    GeneralParams(degree=1, s=(0.0, 1.0, 0, 0, 0), r=(0.1, 0, 0, 0))])
@pytest.mark.parametrize("h", [0.05, 1.0, 3.0])
def test_tustin_matches_scipy(params: GeneralParams, h: float) -> None:
    numd, dend = tustin(params.numerator, params.denominator, h)
    ref_num, ref_den, _ = scipy.signal.cont2discrete((params.numerator, params.denominator), h,
                                                     method="bilinear")
    ref_num, ref_den = np.ravel(ref_num), np.ravel(ref_den)
    if params.degree == 0:  # scipy writes a gain k as k (z - 1)/(z - 1): compare H(z)
        z = np.array([0.3, 2.0, -3.0 + 1.0j])
        assert np.polyval(numd, z) / np.polyval(dend, z) == pytest.approx(
            np.polyval(ref_num, z) / np.polyval(ref_den, z))
        return
    assert numd == pytest.approx(np.ravel(ref_num), rel=1e-10, abs=1e-12)
    assert dend == pytest.approx(ref_den, rel=1e-10, abs=1e-12)


@pytest.mark.parametrize("params", [PIDF, LEAD4])
def test_state_space_steps_the_discrete_transfer_function(params: GeneralParams) -> None:
    h = 0.5
    rng = np.random.default_rng(3)
    e = rng.normal(size=60)
    g = General(params, h)
    u = []
    for ek in e:
        u.append(g.compute(ek))
        g.update(ek)
    numd, dend = tustin(params.numerator, params.denominator, h)
    assert u == pytest.approx(scipy.signal.lfilter(numd, dend, e), abs=1e-10)


def test_degree_zero_is_a_gain() -> None:
    g = General(GeneralParams(degree=0, s=(2.5, 0, 0, 0, 0)), 1.0)
    assert g.compute(0.2) == pytest.approx(0.5)


def test_integrator_ramps_like_the_trapezoidal_rule() -> None:
    g = General(GeneralParams(degree=1, s=(0.0, 0.1, 0, 0, 0), r=(0.0, 0, 0, 0)), 2.0)  # 0.1/s
    u = []
    for _ in range(4):
        u.append(g.compute(1.0))
        g.update(1.0)
    assert u == pytest.approx([0.1, 0.3, 0.5, 0.7])  # 0.1 * h/2 * (1 + 2k)


def test_pole_at_two_over_h_is_refused() -> None:
    unstable = GeneralParams(degree=1, s=(0.0, 1.0, 0, 0, 0), r=(-2.0, 0, 0, 0))  # pole s = 2
    with pytest.raises(ParameterError, match="2/h"):
        General(unstable, 1.0)
    g = General(unstable, 0.5)
    with pytest.raises(ParameterError):
        g.set_sampling_time(1.0)
    assert g.h == 0.5


def running(params: GeneralParams, h: float = 1.0) -> tuple[General, float, float]:
    g = General(params, h)
    e = u = 0.0
    for k in range(25):
        e = 0.2 - 0.005 * k
        u = g.compute(e)
        g.update(e)
    return g, e, u


@pytest.mark.parametrize("new", [LEAD4, GeneralParams(degree=0, s=(4.0, 0, 0, 0, 0)),
                                 GeneralParams(degree=1, s=(1.0, 0.02, 0, 0, 0), r=(0.0, 0, 0, 0))])
def test_coefficient_change_is_bumpless(new: GeneralParams) -> None:
    g, e, u0 = running(PIDF)
    g.set_params(new)
    e1 = e - 0.005
    u1 = g.compute(e1)
    feedthrough = g.discrete()[0][0]  # C(2/h): what the error change alone does at once
    assert abs(u1 - u0) == pytest.approx(abs(feedthrough * (e1 - e)), abs=1e-10)
    fresh = General(new, 1.0).compute(e1)  # the same change without re-initialization
    assert abs(fresh - u0) > 5 * abs(u1 - u0)


def test_coefficient_change_leaves_the_element_at_rest() -> None:
    g, e, u0 = running(PIDF)
    g.set_params(LEAD4)
    out = []
    for _ in range(LEAD4.degree):  # input held: the output stays for n samples
        out.append(g.compute(e))
        g.update(e)
    assert out == pytest.approx([u0] * LEAD4.degree, abs=1e-10)


def test_sampling_time_change_is_bumpless() -> None:
    g, e, u0 = running(PIDF, h=1.0)
    g.set_sampling_time(0.1)
    assert g.compute(e) == pytest.approx(u0, abs=1e-12)
    numd, dend = g.discrete()
    ref_num, ref_den, _ = scipy.signal.cont2discrete((PIDF.numerator, PIDF.denominator), 0.1,
                                                     method="bilinear")
    assert numd == pytest.approx(np.ravel(ref_num))


def test_manual_tracking_then_automatic_is_bumpless() -> None:
    g = General(PIDF, 1.0)
    e = 0.0
    for k in range(20):
        e = 0.1 + 0.002 * k
        g.compute(e)
        g.track(e, 0.45)
    e1 = e + 0.002
    assert abs(g.compute(e1) - 0.45) == pytest.approx(abs(g.discrete()[0][0] * 0.002), abs=1e-10)
    assert abs(General(PIDF, 1.0).compute(e1) - 0.45) > 0.1


@settings(max_examples=40, deadline=None)
@given(
    degree=st.integers(0, 4),
    s=st.tuples(*[st.floats(-5, 5)] * 5),
    poles=st.lists(st.floats(-3.0, -0.01), min_size=4, max_size=4),
)
def test_any_coefficient_change_keeps_the_output(degree: int, s: tuple, poles: list[float]) -> None:
    den = np.poly(poles[:degree]) if degree else np.ones(1)
    r = (*den[1:], *([0.0] * (4 - degree)))
    g, e, u0 = running(PIDF)
    g.set_params(GeneralParams(degree=degree, s=s, r=r))
    assert g.compute(e) == pytest.approx(u0, abs=1e-8)
