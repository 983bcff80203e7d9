"""Injected faults change the simulated process the way physics says (issue 14, B7)."""

from __future__ import annotations

import math

import pytest

from quadtank_tui.core import faults as fx
from quadtank_tui.core.plants import johansson as qt
from quadtank_tui.core.faults import Fault, Faults
from quadtank_tui.core.plants import CoupledCascade, CoupledTITO, QuadTank
from quadtank_tui.engine.sim import SimBackend


def settle(plant, faults: Faults, x, u, seconds: float = 4000.0):
    for _ in range(int(seconds / 100)):
        x = fx.advance(plant, faults, x, u, 100.0)
    return x


def test_without_faults_it_is_the_plant() -> None:
    p = QuadTank(qt.P_MINUS.params)
    assert fx.advance(p, Faults(), qt.P_MINUS.op.x, (3.0, 3.0), 7.0) == qt.advance(
        qt.P_MINUS.op.x, (3.0, 3.0), 7.0, qt.P_MINUS.params)


def test_leak_in_the_upper_cascade_tank_lowers_both_levels_to_the_hand_values() -> None:
    """beta u = (alpha1 + a_leak) sqrt(2 g x1); the lower tank gets alpha1 sqrt(2 g x1),
    so x2 = (alpha1 / alpha2)^2 x1."""
    p = CoupledCascade()
    u = 6.769
    leak = Faults().on(Fault("leak", 1, 0.002))
    x = settle(p, leak, p.steady_state((u,)), (u,))
    x1 = fx.steady_leak_level(p.beta1 * u, p.alpha1, 0.002, p.g)
    assert x1 == pytest.approx((p.beta1 * u / ((p.alpha1 + 0.002) * math.sqrt(2 * p.g))) ** 2)
    assert x[0] == pytest.approx(x1, abs=1e-6)
    assert x[1] == pytest.approx((p.alpha1 / p.alpha2) ** 2 * x1, abs=1e-6)
    assert x1 < 15.0 * 0.7  # 15 cm without the leak


def test_leak_in_quadtank_tank1() -> None:
    p = QuadTank(qt.P_MINUS.params)
    pp = qt.P_MINUS.params
    x = settle(p, Faults().on(Fault("leak", 1, 0.02)), qt.steady_state_levels((3.0, 3.0), pp), (3.0, 3.0))
    q_in = pp.gamma1 * pp.k1 * 3.0 + qt.outflow(x[2], pp.a3, pp.g)
    assert x[0] == pytest.approx(fx.steady_leak_level(q_in, pp.a1, 0.02, pp.g), abs=1e-6)
    assert x[0] == pytest.approx(7.465, abs=1e-3)  # 12.26 cm without it
    assert x[1:] == pytest.approx(qt.steady_state_levels((3.0, 3.0), pp)[1:], abs=1e-6)  # the rest unchanged


def test_clogged_outlet_raises_its_tank_and_leaves_the_flow() -> None:
    """Outlet area times f: x1 = (beta u / (f alpha1 sqrt 2g))^2 = x1_0 / f^2; the same
    flow reaches the lower tank, whose level stays."""
    p = CoupledCascade()
    x0 = p.steady_state((5.0,))
    x = settle(p, Faults().on(Fault("clog", 1, 0.8)), x0, (5.0,))
    assert x[0] == pytest.approx(x0[0] / 0.8**2, abs=1e-6)
    assert x[1] == pytest.approx(x0[1], abs=1e-6)


def test_murray_smith_drain_partly_closed() -> None:
    """Tank 2's drain at 70 %: with the pumps held both levels rise to the steady state
    of the plant whose a2 is 0.7 a2."""
    p = CoupledTITO()
    u = (2.8, 0.7)  # what the pumps settle at in params/murray-smith-drain.yaml
    x = settle(p, Faults().on(Fault("clog", 2, 0.7)), p.steady_state(u), u, 6000.0)
    assert x == pytest.approx(CoupledTITO(a2=0.7 * p.a2).steady_state(u), abs=1e-7)


def test_weak_pump_is_a_lower_voltage() -> None:
    p = QuadTank(qt.P_MINUS.params)
    x = settle(p, Faults().on(Fault("weak_pump", 1, 0.5)), qt.P_MINUS.op.x, (3.0, 3.0), 6000.0)
    assert x == pytest.approx(qt.steady_state_levels((1.5, 3.0), qt.P_MINUS.params), abs=1e-6)


def test_half_a_pump_quarters_the_cascade_levels() -> None:
    """JuliaHub's Dyad example halves one pump: the inflow beta u / 2 leaves through
    each orifice, head ~ flow^2, so both steady levels drop to a quarter (15 cm ->
    3.75 cm, 14.727 -> 3.682 cm)."""
    p = CoupledCascade()
    op = p.steady_inputs((15.0, None))
    x = settle(p, Faults().on(Fault("weak_pump", 1, 0.5)), op.x, op.u, 6000.0)
    assert x == pytest.approx((15.0 / 4, op.x[1] / 4), abs=1e-6)
    assert x[1] == pytest.approx(3.681848, abs=1e-6)


def test_valve_drift_moves_gamma() -> None:
    p = QuadTank(qt.P_MINUS.params)
    f = Faults().on(Fault("valve_drift", 1, -0.001))
    moved = fx.drift_valves(p, f, 100.0)
    assert moved.values()["gamma1"] == pytest.approx(0.6)
    assert fx.drift_valves(p, f, 1e6).values()["gamma1"] == 0.0  # a valve stops at its end


def test_sensor_faults_in_the_simulator() -> None:
    p = qt.P_MINUS.params
    h = qt.steady_state_levels((3.0, 3.0), p)
    sim = SimBackend(p, h)
    sim.write_pumps((0.3, 0.3))
    true = sim.read_levels()
    sim.set_fault(Fault("sensor_bias", 1, 0.05))
    assert sim.read_levels()[0] == pytest.approx(true[0] + 0.05, abs=1e-9)
    sim.set_fault(Fault("sensor_drift", 2, 0.001))
    sim.elapse(10.0)
    assert sim.read_levels()[1] == pytest.approx(true[1] + 0.01, abs=1e-6)
    sim.clear_fault("sensor_bias", 1)
    sim.clear_fault("sensor_drift", 2)
    sim.set_fault(Fault("sensor_stuck", 3))
    stuck = sim.read_levels()[2]
    sim.write_pumps((0.0, 0.0))
    sim.elapse(30.0)
    assert sim.read_levels()[2] == stuck and sim.levels_cm[2] < h[2] - 0.5
    sim.clear_fault("sensor_stuck", 3)
    sim.set_fault(Fault("sensor_noise", 4, 0.01))
    dev = [sim.read_levels()[3] - p.kc * sim.levels_cm[3] / 10 for _ in range(2000)]
    mean = sum(dev) / len(dev)
    std = math.sqrt(sum((d - mean) ** 2 for d in dev) / len(dev))
    assert abs(mean) < 0.001 and std == pytest.approx(0.01, rel=0.06)
    assert sim.faults.labels() == "sensor noise sensor 4 (0.01)"


@pytest.mark.parametrize("fault, plant, message", [
    (Fault("leak", 5, 0.01), QuadTank(), "tank must be 1..4"),
    (Fault("leak", 1, 40.0), QuadTank(), "area must be in"),
    (Fault("clog", 1, 1.0), CoupledCascade(), "open fraction"),
    (Fault("weak_pump", 2, 0.5), CoupledCascade(), "pump must be 1..1"),
    (Fault("valve_drift", 1, 0.01), CoupledTITO(), "has no valves"),
    (Fault("flood", 1, 0.01), CoupledTITO(), "unknown fault"),
])
def test_impossible_faults_are_refused(fault: Fault, plant, message: str) -> None:
    with pytest.raises(fx.FaultError, match=message):
        fx.check_fault(fault, plant)


def test_one_fault_of_a_kind_per_target() -> None:
    f = Faults().on(Fault("leak", 1, 0.01)).on(Fault("leak", 1, 0.02)).on(Fault("leak", 2, 0.01))
    assert [x.value for x in f.of("leak")] == [0.02, 0.01]
    assert f.off("leak", 1).labels() == "leak tank 2 (0.01)"
    assert not Faults()
