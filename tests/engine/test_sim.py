"""The simulator backend: normalized I/O over the accurate nonlinear model, and the
disturbances only a simulation offers."""

from __future__ import annotations

import pytest

from quadtank_tui.core.plants.common import PlantError
from quadtank_tui.core.plants.johansson import P_MINUS, advance, steady_state_levels
from quadtank_tui.engine.sim import SimBackend


def test_normalized_io_is_kc_h_over_10_and_10u_volts() -> None:
    p = P_MINUS.params
    sim = SimBackend(p, (12.4, 12.7, 1.8, 1.4))
    assert sim.read_levels() == pytest.approx((0.62, 0.635, 0.09, 0.07))
    sim.write_pumps((0.3, 0.25))
    assert sim.voltages == (3.0, 2.5)
    sim.elapse(10.0)
    assert sim.levels_cm == advance((12.4, 12.7, 1.8, 1.4), (3.0, 2.5), 10.0, p)


def test_steady_state_stays_put_and_safe_state_stops_the_pumps() -> None:
    p = P_MINUS.params
    h = steady_state_levels((3.0, 3.0), p)
    sim = SimBackend(p, h)
    sim.write_pumps((0.3, 0.3))
    sim.elapse(100.0)
    assert sim.levels_cm == pytest.approx(h, abs=1e-6)
    sim.safe_state()
    assert sim.voltages == (0.0, 0.0)
    sim.elapse(5.0)
    assert sim.levels_cm[0] < h[0]


def test_add_water_valve_change_and_reset() -> None:
    p = P_MINUS.params
    sim = SimBackend(p, (12.4, 12.7, 1.8, 1.4))
    sim.add_water(3, 0.05)  # 0.05 normalized = 1 cm at kc = 0.5
    assert sim.levels_cm[2] == pytest.approx(2.8)
    sim.add_water(1, 1.0)  # overflow spills at the brim
    assert sim.levels_cm[0] == p.hmax
    with pytest.raises(PlantError):
        sim.add_water(5, 0.1)
    sim.set_params(p.with_valves(gamma1=0.4))
    assert sim.params.gamma1 == 0.4 and sim.levels_cm[0] == p.hmax  # water stays
    sim.write_pumps((0.5, 0.5))
    sim.reset()
    assert sim.levels_cm == (12.4, 12.7, 1.8, 1.4) and sim.voltages == (0.0, 0.0)
