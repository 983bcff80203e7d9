"""Every plant behind the interface: steady states both ways, linearization against
finite differences, limits, and the quadruple-tank adapter's bit-for-bit identity
with core.plants.johansson (issue 14)."""

from __future__ import annotations

import numpy as np
import pytest

from quadtank_tui.core.plants import johansson as qt
from quadtank_tui.core.analysis import linearize as qt_linearize
from quadtank_tui.core.plants import (
    KINDS,
    CoupledCascade,
    CoupledTITO,
    DesautelQTP,
    Plant,
    PlantError,
    QuadTank,
    SteadyStateError,
    make_plant,
)

# kind -> (a plant, pump voltages of a typical operating point)
CASES: dict[str, tuple[Plant, tuple[float, ...]]] = {
    "quadtank": (QuadTank(qt.P_MINUS.params), (3.0, 3.0)),
    "desautel-qtp": (DesautelQTP(), (6.0, 6.0)),
    "coupled-cascade": (CoupledCascade(), (6.769,)),
    "coupled-tito": (CoupledTITO(), (3.0, 1.0)),
}


def test_every_kind_is_covered() -> None:
    assert set(CASES) == set(KINDS)


@pytest.mark.parametrize("kind", list(CASES))
def test_steady_state_is_an_equilibrium(kind: str) -> None:
    p, u = CASES[kind]
    x = p.steady_state(u)
    f = np.array(p.rhs(x, u))
    scale = max(s.hi for s in p.states)
    assert np.abs(f).max() < 1e-12 * scale, f
    assert all(s.lo < xi < s.hi for xi, s in zip(x, p.states))


@pytest.mark.parametrize("kind", list(CASES))
def test_steady_state_both_ways(kind: str) -> None:
    """Levels from voltages, and voltages back from the levels that set them."""
    p, u = CASES[kind]
    x = p.steady_state(u)
    request: list[float | None] = [None] * len(x)
    for i in p.controlled if kind != "coupled-cascade" else (0,):
        request[i] = x[i]
    op = p.steady_inputs(request)
    assert op.u == pytest.approx(u, rel=1e-9)
    assert op.x == pytest.approx(x, rel=1e-9)


@pytest.mark.parametrize("kind", list(CASES))
def test_linearization_matches_finite_differences(kind: str) -> None:
    p, u = CASES[kind]
    x0 = np.array(p.steady_state(u)) * 1.03  # off equilibrium: A depends on the levels only
    m = p.linearize(tuple(x0), u)
    n, k = len(x0), len(u)
    hx = 1e-6 * max(s.hi for s in p.states)
    A = np.empty((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = hx
        A[:, j] = (np.array(p.rhs(tuple(x0 + e), u)) - np.array(p.rhs(tuple(x0 - e), u))) / (2 * hx)
    B = np.empty((n, k))
    for j in range(k):
        e = np.zeros(k)
        e[j] = 1e-4
        B[:, j] = (np.array(p.rhs(tuple(x0), tuple(np.array(u) + e))) - np.array(p.rhs(tuple(x0), tuple(np.array(u) - e)))) / 2e-4
    C = np.empty((len(p.outputs), n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = hx
        C[:, j] = (np.array(p.output(tuple(x0 + e))) - np.array(p.output(tuple(x0 - e)))) / (2 * hx)
    np.testing.assert_allclose(m.A, A, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(m.B, B, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(m.C, C, rtol=1e-9)
    assert np.all(m.poles().real < 0)


@pytest.mark.parametrize("kind", list(CASES))
def test_levels_stay_in_their_limits(kind: str) -> None:
    """Pumps at full (and beyond), then off: tanks brim and empty, never past a limit."""
    p, _ = CASES[kind]
    lo = np.array([s.lo for s in p.states])
    hi = np.array([s.hi for s in p.states])
    x = tuple(0.5 * (lo + hi))
    seen_brim = False
    for u in ([2 * s.hi for s in p.inputs], [-1.0 for _ in p.inputs]):
        for _ in range(60):
            x = p.advance(x, u, 20.0)
            assert np.all(np.array(x) >= lo) and np.all(np.array(x) <= hi)
            seen_brim |= any(xi == h for xi, h in zip(x, hi))
    assert seen_brim


@pytest.mark.parametrize("kind", list(CASES))
def test_inputs_saturate_at_the_pump_range(kind: str) -> None:
    p, _ = CASES[kind]
    top = [s.hi for s in p.inputs]
    x = p.steady_state([0.3 * t for t in top])
    assert p.rhs(x, [2 * t for t in top]) == p.rhs(x, top) or kind in ("quadtank", "desautel-qtp")
    assert p.advance(x, [2 * t for t in top], 3.0) == p.advance(x, top, 3.0)
    assert p.advance(x, [-5.0] * len(top), 3.0) == p.advance(x, [0.0] * len(top), 3.0)


def test_make_plant_and_bad_values() -> None:
    assert make_plant("coupled-cascade", {"beta1": 0.3}).values()["beta1"] == 0.3
    with pytest.raises(PlantError, match="unknown plant"):
        make_plant("triple-tank")
    with pytest.raises(PlantError, match="no constant"):
        make_plant("coupled-tito", {"alpha9": 1.0})
    with pytest.raises(PlantError, match="alpha2"):
        make_plant("coupled-cascade", {"alpha2": -1.0})
    with pytest.raises(PlantError, match="gamma1"):
        make_plant("quadtank", {"gamma1": 1.5})


# --- the quadruple tank adapter ---------------------------------------------------------

def test_quadtank_adapter_is_core_plant_bit_for_bit() -> None:
    p = qt.P_PLUS.params
    a = QuadTank(p)
    h = qt.P_PLUS.op.x
    for v in ((3.15, 3.15), (0.0, 6.0), (10.0, 0.0)):
        assert a.advance(h, v, 1.7) == qt.advance(h, v, 1.7, p)
        assert a.rhs(h, v) == qt.rhs(h, v, p)
        assert a.steady_state(v) == qt.steady_state_levels(v, p)
    m, ref = a.control_model(h), qt_linearize(p, h)
    np.testing.assert_array_equal(m.A, ref.A)
    np.testing.assert_array_equal(m.B, ref.B)
    np.testing.assert_array_equal(m.C, ref.C)
    op = a.steady_inputs((12.6, 13.0))
    ref_op = qt.steady_state_inputs(12.6, 13.0, p)
    assert op.u == ref_op.u and op.x == ref_op.x


def test_quadtank_adapter_zeros_are_the_published_ones() -> None:
    """control.md: P- at the table's levels gives zeros -0.0580, -0.0172."""
    z = QuadTank(qt.P_MINUS.params).control_model(qt.P_MINUS.op.x).zeros()
    assert z.real == pytest.approx([-0.0580, -0.0172], abs=5e-5)


def test_quadtank_unreachable_levels_are_refused() -> None:
    with pytest.raises(SteadyStateError):
        QuadTank(qt.P_PLUS.params).steady_inputs((14.0, 2.0))
    with pytest.raises(SteadyStateError, match="lower levels"):
        QuadTank().steady_inputs((None, 10.0))


# --- the two-input coupled tanks: flow reversal --------------------------------------------

def test_tito_orifice_flow_reverses_when_tank2_is_higher() -> None:
    p = CoupledTITO()
    q12, _ = p.flows((0.10, 0.20))
    assert q12 == pytest.approx(-p.Cd1 * p.a1 * np.sqrt(2 * p.g * 0.10))
    f = p.rhs((0.10, 0.20), (0.0, 0.0))
    assert f[0] > 0  # tank 1 fills from tank 2
    x = p.advance((0.10, 0.20), (0.0, 0.0), 5.0)
    assert x[0] > 0.10 and x[1] < 0.20


def test_tito_pump2_alone_levels_meet() -> None:
    """Murray-Smith 5.3: with pump 1 off the tanks settle at one level (tank 1 has no
    other outlet), H2 = H3 + (Gp v2 / (Cd2 a2))^2 / 2g."""
    p = CoupledTITO()
    expected = p.H3 + (p.Gp * 4.0 / (p.Cd2 * p.a2)) ** 2 / (2 * p.g)
    assert p.steady_state((0.0, 4.0)) == pytest.approx((expected, expected), rel=1e-12)
    x: tuple[float, ...] = (0.05, 0.05)
    for _ in range(40):
        x = p.advance(x, (0.0, 4.0), 100.0)
    assert x == pytest.approx((expected, expected), abs=1e-6)


def test_tito_refuses_h1_below_h2_and_names_why() -> None:
    with pytest.raises(SteadyStateError, match="no other outlet"):
        CoupledTITO().steady_inputs((0.105, 0.131))


def test_tito_published_operating_point_needs_a_negative_inflow() -> None:
    """Reported, not forced: at H1 = 0.115, H2 = 0.071 m the drain passes less than
    the orifice, so Qi2 = -3.13e-6 m^3/s (-0.43 V). The linearization depends on the
    levels only, so Murray-Smith's design figures are unaffected."""
    p = CoupledTITO()
    q12, drain = p.flows((0.115, 0.071))
    assert drain - q12 == pytest.approx(-3.129e-6, rel=1e-3)
    with pytest.raises(SteadyStateError, match="backwards"):
        p.steady_inputs((0.115, 0.071))


def test_tito_drains_to_h3_and_never_below() -> None:
    p = CoupledTITO()
    x: tuple[float, ...] = (0.2, 0.1)
    for _ in range(100):
        x = p.advance(x, (0.0, 0.0), 60.0)
        assert min(x) >= p.H3 - 1e-9  # the drain stops at H3 (to the solver tolerance)
    assert x == pytest.approx((p.H3, p.H3), abs=1e-4)


@pytest.mark.parametrize("u", [(6.9, 0.0), (6.9, 6.9), (0.0, 6.9), (4.0, 6.0)])  # the first two brim
def test_tito_steady_state_at_the_brim_is_an_equilibrium(u: tuple[float, float]) -> None:
    """A brimming tank spills: the steady state still has dx/dt = 0 (spill rule)."""
    p = CoupledTITO()
    x = p.steady_state(u)
    assert np.abs(p.rhs(x, u)).max() < 1e-9
    assert p.advance(x, u, 500.0) == pytest.approx(x, abs=1e-9)


def test_importing_the_parameters_and_the_loop_loads_no_analysis_stack() -> None:
    """python-control and scipy (a second or two) load only when a linearization asks."""
    import subprocess
    import sys
    code = ("import sys, quadtank_tui.core.parameters, quadtank_tui.engine.loop\n"
            "print(sorted(m for m in ('control', 'scipy') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
