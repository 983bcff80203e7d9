"""Property tests over random valid parameters (issue 2)."""

from __future__ import annotations

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from quadtank_tui.core.analysis import analyze, linearize
from quadtank_tui.core.plants.johansson import PlantParams, advance, rhs, steady_state_levels, total_volume

areas = st.floats(15.0, 60.0)
outlets = st.floats(0.03, 0.15)
gains = st.floats(1.0, 6.0)
valves = st.floats(0.05, 1.0)


@st.composite
def plants(draw, valves=valves) -> PlantParams:
    return PlantParams(
        A1=draw(areas), A2=draw(areas), A3=draw(areas), A4=draw(areas),
        a1=draw(outlets), a2=draw(outlets), a3=draw(outlets), a4=draw(outlets),
        k1=draw(gains), k2=draw(gains), gamma1=draw(valves), gamma2=draw(valves),
    )


levels = st.tuples(*[st.floats(0.5, 19.5)] * 4)
volts = st.tuples(st.floats(0.5, 10.0), st.floats(0.5, 10.0))


@settings(max_examples=150, deadline=None)
@given(plants(), levels)
def test_rhp_zero_iff_valves_sum_below_one(p: PlantParams, h0) -> None:
    s = p.gamma1 + p.gamma2
    assume(abs(s - 1.0) > 1e-3)
    r = analyze(p, h0)
    has_rhp = any(z.real > 0 for z in r.zeros)
    assert has_rhp == (s < 1.0)
    assert (r.phase == "minimum") == (s > 1.0)


@settings(max_examples=60, deadline=None)
@given(plants(valves=st.floats(0.0, 1.0)), st.tuples(st.floats(0.0, 10.0), st.floats(0.0, 10.0)))
def test_simulation_settles_at_analytic_steady_state(p: PlantParams, v) -> None:
    """Over the whole valve and pump range, including a pump off or a valve sending
    everything one way (tanks that hold only a film of water: plant.H_FILM)."""
    target = steady_state_levels(v, p)
    h = (5.0, 5.0, 5.0, 5.0)
    for _ in range(200):  # at most 20,000 s; most plants are there within 1000 s
        h = advance(h, v, 100.0, p)
        if np.allclose(h, target, rtol=1e-6, atol=1e-6):
            break
    # ... and it stays: the level reached is a rest, not a crossing.
    h = advance(h, v, 100.0, p)
    assert np.allclose(h, target, rtol=1e-6, atol=1e-6)


@settings(max_examples=40, deadline=None)
@given(plants(), levels)
def test_pumps_off_water_only_decreases(p: PlantParams, h0) -> None:
    h = h0
    vol = total_volume(h, p)
    for _ in range(30):
        h = advance(h, (0.0, 0.0), 20.0, p)
        new = total_volume(h, p)
        assert new <= vol + 1e-9
        assert all(0.0 <= x <= p.hmax for x in h)
        vol = new


@settings(max_examples=60, deadline=None)
@given(plants(), levels, volts)
def test_linearization_matches_finite_differences(p: PlantParams, h0, v) -> None:
    m = linearize(p, h0)
    J = _central_differences(lambda h: rhs(h, v, p), h0)
    Bn = _central_differences(lambda u: rhs(h0, u, p), v)
    assert np.allclose(m.A, J, rtol=1e-5, atol=1e-8)
    assert np.allclose(m.B, Bn, rtol=1e-5, atol=1e-8)


def _central_differences(f, x, eps: float = 1e-6) -> np.ndarray:
    """d f / d x by central differences, one column per component of x."""
    cols = []
    for j in range(len(x)):
        xp, xm = list(x), list(x)
        xp[j] += eps
        xm[j] -= eps
        cols.append((np.array(f(xp)) - np.array(f(xm))) / (2 * eps))
    return np.column_stack(cols)
