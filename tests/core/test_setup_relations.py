"""Setup-screen relations: op. point, diameter and time constant of a tank stay
consistent with one hidden outlet area (control.md; thesis 5.4, Figure 39)."""

from __future__ import annotations

import math

import pytest

from quadtank_tui.core.parameters import PRESET, Parameters
from quadtank_tui.core.plants.johansson import P_MINUS, area_from_diameter, time_constant
from quadtank_tui.core.setup_relations import (
    apply_changes,
    edit_by_key,
    edit_tank,
    outlet,
    tank_keys,
    tank_setup,
)
from quadtank_tui.core.ranges import ParameterError

#: Thesis Figure 39, the Tank 1 window of the Setup screen.
FIG39 = {"SIMULATION.OpPoint1": 0.62, "SIMULATION.Diameter1": 5.93, "SIMULATION.TimeConst1": 62.16}
G = 981.0


@pytest.fixture
def fig39() -> Parameters:
    return PRESET.with_values(FIG39)


def test_outlet_of_figure_39(fig39: Parameters) -> None:
    # 0.62 normalized at kc = 0.5 V/cm is 12.4 cm; A = pi 5.93^2 / 4 = 27.62 cm^2.
    a = outlet(fig39.simulation, 1)
    assert a == pytest.approx(area_from_diameter(5.93) * math.sqrt(2 * 12.4 / G) / 62.16, rel=1e-12)
    assert a == pytest.approx(0.07065, abs=5e-5)  # the rig's a1 = 0.071 cm^2, to its precision
    # ... and it is the outlet the simulated plant uses.
    assert fig39.quadtank_constants().a1 == pytest.approx(a, rel=1e-12)


def test_diameter_recomputes_time_constant_through_the_fixed_outlet(fig39: Parameters) -> None:
    e = edit_tank(fig39.simulation, 1, diameter=6.5)
    t = e.get(1)
    assert t.outlet == pytest.approx(outlet(fig39.simulation, 1), rel=1e-14)
    assert t.time_constant == pytest.approx(62.16 * (6.5 / 5.93) ** 2, abs=1e-6)
    assert t.time_constant == pytest.approx(74.6841, abs=1e-4)
    assert e.changes() == {"SIMULATION.Diameter1": 6.5, "SIMULATION.TimeConst1": t.time_constant}


def test_op_point_recomputes_time_constant_through_the_fixed_outlet(fig39: Parameters) -> None:
    e = edit_tank(fig39.simulation, 1, op_point=0.31)  # half the level: T / sqrt(2)
    assert e.get(1).time_constant == pytest.approx(62.16 / math.sqrt(2), abs=1e-6)
    # Same as T from the physics at the new level with the old outlet.
    a = outlet(fig39.simulation, 1)
    assert e.get(1).time_constant == pytest.approx(time_constant(area_from_diameter(5.93), a, 6.2, G), abs=1e-6)
    assert set(e.changes()) == {"SIMULATION.OpPoint1", "SIMULATION.TimeConst1"}


def test_time_constant_moves_the_outlet_only(fig39: Parameters) -> None:
    e = edit_tank(fig39.simulation, 1, time_constant=124.32)
    t = e.get(1)
    assert (t.op_point, t.diameter, t.time_constant) == (0.62, 5.93, 124.32)
    assert t.outlet == pytest.approx(outlet(fig39.simulation, 1) / 2, rel=1e-12)
    assert e.changes() == {"SIMULATION.TimeConst1": 124.32}


def test_a_round_trip_restores_the_time_constant(fig39: Parameters) -> None:
    sim = edit_tank(fig39.simulation, 1, diameter=7.0).after
    sim = edit_tank(sim, 1, diameter=5.93).after
    assert sim.time_constants[0] == pytest.approx(62.16, rel=1e-14)


def test_valves_only_on_the_lower_tanks_and_in_range() -> None:
    sim = PRESET.simulation
    e = edit_tank(sim, 2, valve=0.34)
    assert e.after.valves == (0.7, 0.34) and e.changes() == {"SIMULATION.Valve2": 0.34}
    with pytest.raises(ParameterError) as info:
        edit_tank(sim, 3, valve=0.5)
    assert info.value.field == "SIMULATION.Valve3"
    for bad in (-0.01, 1.2):
        with pytest.raises(ParameterError) as info:
            edit_tank(sim, 1, valve=bad)
        assert info.value.field == "SIMULATION.Valve1"


def test_refused_values_name_the_key_and_change_nothing() -> None:
    sim = PRESET.simulation
    with pytest.raises(ParameterError) as info:
        edit_tank(sim, 4, diameter=0.0)
    assert info.value.field == "SIMULATION.Diameter4"
    with pytest.raises(ParameterError) as info:
        edit_tank(sim, 3, op_point=1.5)
    assert info.value.field == "SIMULATION.OpPoint3"
    with pytest.raises(ParameterError) as info:
        edit_tank(sim, 1, time_constant=0.5)
    assert info.value.field == "SIMULATION.TimeConst1"
    assert PRESET.simulation == sim


def test_the_preset_is_the_paper_setting() -> None:
    t = tank_setup(PRESET.simulation, 3)
    assert t.valve is None
    assert t.outlet == pytest.approx(P_MINUS.params.a3, rel=1e-5)
    assert tank_keys(3) == ("SIMULATION.OpPoint3", "SIMULATION.Diameter3", "SIMULATION.TimeConst3")
    assert tank_keys(1)[-1] == "SIMULATION.Valve1"


def test_by_key_and_in_sequence(fig39: Parameters) -> None:
    e = edit_by_key(fig39.simulation, "SIMULATION.Diameter1", 6.5)
    assert e.after == edit_tank(fig39.simulation, 1, diameter=6.5).after
    sim = apply_changes(fig39.simulation, {"SIMULATION.Valve1": 0.43, "SIMULATION.Valve2": 0.34})
    assert sim.valves == (0.43, 0.34)
    with pytest.raises(KeyError):
        edit_by_key(fig39.simulation, "SIMULATION.Pump1", 3.0)
    # What Set sends is accepted by the parameter model as it stands.
    assert fig39.with_values(e.changes()).simulation == e.after


@pytest.mark.parametrize("field, value", [("diameter", 1e308), ("op_point", 1e308), ("diameter", 1e200)])
def test_an_absurd_value_is_refused_by_its_range_not_an_overflow(field: str, value: float) -> None:
    """Issue 18.10: 1e308 in a Diameter overflowed while scaling the time constant."""
    key = {"diameter": "Diameter1", "op_point": "OpPoint1"}[field]
    with pytest.raises(ParameterError, match=f"SIMULATION.{key}: must be <= "):
        edit_tank(PRESET.simulation, 1, **{field: value})
