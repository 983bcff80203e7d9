"""PID element: known values for each part, anti-windup, bumpless changes."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given, settings, strategies as st

from quadtank_tui.core.controllers.pid import PID, PIDParams
from quadtank_tui.core.ranges import ParameterError

P_ONLY = PIDParams(K=2.0, integral=False)


def test_p_only_step() -> None:
    c = PID(P_ONLY, 1.0)
    assert c.compute(0.1, 0.0) == pytest.approx(0.2)
    assert c.compute(0.5, 0.3) == pytest.approx(0.4)


def test_setpoint_weight_b_scales_the_reference_in_p() -> None:
    c = PID(PIDParams(K=2.0, b=0.25, integral=False), 1.0)
    assert c.compute(0.4, 0.0) == pytest.approx(2.0 * 0.25 * 0.4)
    assert c.compute(0.0, 0.1) == pytest.approx(-0.2)  # y is never weighted


def test_integral_ramps_k_h_over_ti_per_sample() -> None:
    K, Ti, h, e = 2.0, 10.0, 0.5, 0.1
    c = PID(PIDParams(K=K, Ti=Ti, b=0.0), h)
    v = []
    for _ in range(6):
        v.append(c.compute(e, 0.0))
        c.update(e, 0.0, v[-1])  # unsaturated: the tracking term is zero
    steps = [b - a for a, b in zip(v, v[1:])]
    assert v[0] == 0.0
    assert steps == pytest.approx([K * h / Ti * e] * 5, rel=1e-12)


def test_integral_switched_off_does_not_ramp() -> None:
    c = PID(PIDParams(K=1.0, integral=False), 1.0)
    for _ in range(5):
        v = c.compute(0.1, 0.0)
        c.update(0.1, 0.0, v)
    assert c.compute(0.1, 0.0) == pytest.approx(0.1)


def derivative_response(params: PIDParams, h: float, r: list[float], y: list[float]) -> list[float]:
    c = PID(params, h)
    out = []
    for rk, yk in zip(r, y):
        out.append(c.compute(rk, yk))
        c.update(rk, yk, out[-1])
    return out


def test_derivative_filter_has_time_constant_td_over_n() -> None:
    K, Td, N, h = 1.5, 10.0, 5.0, 0.1
    p = PIDParams(K=K, Td=Td, N=N, integral=False, derivative=True)
    y = [0.0] + [0.1] * 60
    v = derivative_response(p, h, [0.0] * 61, y)
    D = [vk + K * yk for vk, yk in zip(v, y)]  # remove P = -K y
    assert D[0] == 0.0
    assert D[1] == pytest.approx(-K * Td * N / (Td + N * h) * 0.1)  # kick limited to K N
    ratios = [b / a for a, b in zip(D[1:], D[2:])]
    assert ratios == pytest.approx([Td / (Td + N * h)] * len(ratios))
    # Backward difference of a lag T: 1/ad = 1 + h/T, so T = Td/N exactly ...
    assert h / (1 / ratios[0] - 1) == pytest.approx(Td / N)
    # ... and after T = Td/N = 2 s (20 samples) the kick has decayed to about 1/e.
    assert D[21] / D[1] == pytest.approx(math.exp(-1), rel=0.03)


def test_derivative_setpoint_weight_a() -> None:
    base: dict[str, Any] = dict(K=1.0, Td=4.0, N=8.0, integral=False, derivative=True, b=0.0)
    r = [0.0, 0.1, 0.1]
    with_a = derivative_response(PIDParams(a=1.0, **base), 0.5, r, [0.0] * 3)
    without = derivative_response(PIDParams(a=0.0, **base), 0.5, r, [0.0] * 3)
    y = [0.0, -0.1, -0.1]
    as_y = [v + 1.0 * yk for v, yk in  # D part only: remove P = -K y
            zip(derivative_response(PIDParams(a=0.0, **base), 0.5, [0.0] * 3, y), y)]
    assert without == [0.0, 0.0, 0.0]
    assert with_a[1] == pytest.approx(1.0 * 4.0 * 8.0 / (4.0 + 8.0 * 0.5) * 0.1)
    assert with_a == pytest.approx(as_y)  # a = 1: a step in r acts like a step in -y


def test_derivative_switched_off() -> None:
    p = PIDParams(K=1.0, Td=4.0, N=8.0, integral=False, derivative=False)
    assert derivative_response(p, 0.5, [0.0] * 3, [0.0, 0.1, 0.1]) == pytest.approx([0.0, -0.1, -0.1])


def test_invalid_parameters_name_the_field() -> None:
    cases: tuple[tuple[str, dict[str, Any]], ...] = (("Ti", {"Ti": 0.0}), ("Tr", {"Tr": -1.0}), ("N", {"N": 0.0}),
                                                     ("a", {"a": 1.5}), ("b", {"b": -0.1}))
    for field, kwargs in cases:
        with pytest.raises(ParameterError) as err:
            PIDParams(**kwargs)
        assert err.value.field == field


def windup_recovery_time(anti_windup: bool) -> float:
    """PI on a first-order lag y' = (0.8 u - y)/20 whose input saturates at 1: r = 0.95
    is out of reach for 200 s (u stuck at 1, the integral winds up), then r = 0.5.
    Returns the time from the setpoint change until y stays within 0.02 of 0.5."""
    h, T, gain = 0.5, 20.0, 0.8
    c = PID(PIDParams(K=1.0, Ti=20.0, Tr=1.0), h, anti_windup=anti_windup)
    a = math.exp(-h / T)
    y, ys = 0.0, []
    n1, n2 = int(200 / h), int(600 / h)
    for k in range(n1 + n2):
        r = 0.95 if k < n1 else 0.5
        v = c.compute(r, y)
        u = min(1.0, max(0.0, v))
        c.update(r, y, u)
        y = a * y + (1 - a) * gain * u
        ys.append(y)
    last_out = max(k for k in range(n1, n1 + n2) if abs(ys[k] - 0.5) > 0.02)
    return (last_out + 1 - n1) * h


def test_back_calculation_recovers_at_least_three_times_faster() -> None:
    with_aw, without = windup_recovery_time(True), windup_recovery_time(False)
    assert with_aw == pytest.approx(40.5, abs=1.0)
    assert without == pytest.approx(165.5, abs=1.0)
    assert without / with_aw >= 3.0


def running(params: PIDParams, h: float = 1.0, n: int = 10) -> tuple[PID, float, float, float]:
    """A PID mid-transient: error e = r - y nonzero; returns (pid, r, y, last v)."""
    c = PID(params, h)
    r, y = 0.6, 0.4
    v = 0.0
    for k in range(n):
        y = 0.4 + 0.01 * k
        v = c.compute(r, y)
        c.update(r, y, v)
    return c, r, y, v


def test_parameter_change_is_bumpless() -> None:
    old = PIDParams(K=1.0, Ti=30.0, b=1.0)
    new = PIDParams(K=3.0, Ti=10.0, b=0.5)
    c, r, y, v0 = running(old)
    c.set_params(new)
    y1 = y + 0.01
    v1 = c.compute(r, y1)
    # What the error alone moves u by under the new law: P's change and one integral step.
    by_error = abs(new.K * (y1 - y)) + abs(new.K * 1.0 / new.Ti * (r - y))
    assert abs(v1 - v0) <= by_error + 1e-12
    naive = abs((new.K * (new.b * r - y1)) - (old.K * (old.b * r - y1)))  # no absorption
    assert naive > 20 * abs(v1 - v0)


def test_parameter_change_without_integral_uses_the_bias() -> None:
    c, r, y, v0 = running(PIDParams(K=1.0, integral=False))
    c.set_params(PIDParams(K=4.0, integral=False))
    assert c.compute(r, y) == pytest.approx(v0)


@settings(max_examples=80, deadline=None)
@given(
    K=st.floats(-5, 5), Ti=st.floats(1, 300), Td=st.floats(0, 50), N=st.floats(1, 20),
    a=st.floats(0, 1), b=st.floats(0, 1), integral=st.booleans(), derivative=st.booleans(),
)
def test_any_parameter_change_leaves_v_at_the_last_sample_unchanged(
    K: float, Ti: float, Td: float, N: float, a: float, b: float, integral: bool, derivative: bool
) -> None:
    c, r, y, _ = running(PIDParams(K=2.0, Ti=20.0, Td=5.0, N=10.0, derivative=True), n=5)
    before = c.compute(r, y)
    c.set_params(PIDParams(K=K, Ti=Ti, Td=Td, N=N, a=a, b=b, integral=integral, derivative=derivative))
    assert c.compute(r, y) == pytest.approx(before, abs=1e-9)
    c.set_sampling_time(0.25)
    assert c.compute(r, y) == pytest.approx(before, abs=1e-9)


def test_manual_to_automatic_is_bumpless() -> None:
    p = PIDParams(K=2.0, Ti=20.0, Td=3.0, N=10.0, derivative=True)
    c = PID(p, 1.0)
    r, y = 0.5, 0.3
    for k in range(30):  # manual: the operator moves u, the level follows
        u_manual = 0.3 + 0.005 * k
        y = 0.3 + 0.002 * k
        c.compute(r, y)
        c.track(r, y, u_manual)
    y1 = y + 0.002
    v1 = c.compute(r, y1)
    # The error alone moves P by K dy and the filtered derivative by bd dy plus its
    # own decay (1 - ad) D.
    ad = p.Td / (p.Td + p.N * 1.0)
    bd = p.K * p.N * ad
    by_error = (p.K + bd) * abs(y1 - y) + (1 - ad) * abs(c.derivative_state)
    assert abs(v1 - u_manual) <= by_error + 1e-12
    assert abs(v1 - u_manual) < 0.05
    # Without tracking the controller would start from its empty integrator.
    assert abs(PID(p, 1.0).compute(r, y1) - u_manual) > 0.15


def test_reset_forgets_everything() -> None:
    c, r, y, _ = running(PIDParams(K=1.0, Ti=5.0))
    c.reset()
    assert c.integral_state == 0.0 and c.derivative_state == 0.0
    assert c.compute(r, y) == pytest.approx(1.0 * (r - y))
