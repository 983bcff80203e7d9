"""The effects a real cascade shows (core.plants.coupled.CoupledCascade): an upper
tank that overflows into the lower one, a sensor that saturates at its range, a pump
that moves no water below a threshold. Off by default; in the `.par` only when on."""

from __future__ import annotations

import pytest

from quadtank_tui.core.parameters import PLANT_SETTINGS
from quadtank_tui.core.plants.common import PlantError
from quadtank_tui.core.plants import CoupledCascade
from quadtank_tui.files.par import format_par, parse_par

PLAIN = CoupledCascade()


def test_off_by_default_the_model_is_desautels() -> None:
    rig = CoupledCascade(spill1=0.0, vmin=0.0, ysat1=0.0, ysat2=0.0)
    assert rig == PLAIN and PLAIN.effect_names == (
        "spill1", "vmin", "ysat1", "ysat2", "lam1", "lam2", "area1", "off1", "off2")
    # a full upper tank: what would raise it leaves the process
    assert PLAIN.rhs((30.0, 10.0), (20.0,)) == (0.0, PLAIN._q(30.0, PLAIN.alpha1) - PLAIN._q(10.0, PLAIN.alpha2))


def test_the_overflow_falls_into_the_tank_below_in_the_fitted_fraction() -> None:
    rig = CoupledCascade(spill1=0.4)
    q1, q2 = rig._q(30.0, rig.alpha1), rig._q(10.0, rig.alpha2)
    excess = rig.beta1 * 20.0 - q1
    assert excess > 0
    assert rig.rhs((30.0, 10.0), (20.0,)) == (0.0, pytest.approx(q1 - q2 + 0.4 * excess, rel=1e-15))
    assert rig.rhs((29.0, 10.0), (20.0,)) == PLAIN.rhs((29.0, 10.0), (20.0,))  # not full: no spill
    wide = rig.with_values(alpha2=0.015)  # a lower outlet that passes it all
    assert isinstance(wide, CoupledCascade)
    x1, x2 = wide.steady_state((20.0,))  # at rest tank 2 passes its share of the excess too
    assert x1 == 30.0 and x2 < 30.0 and wide._q(x2, wide.alpha2) == pytest.approx(q1 + 0.4 * excess, rel=1e-9)
    assert rig.steady_state((20.0,)) == (30.0, 30.0)  # Desautel's outlets: both brim over


def test_a_sensor_saturates_at_its_range() -> None:
    rig = CoupledCascade(ysat2=4.5)
    assert rig.output((10.0, 10.0)) == PLAIN.output((10.0, 10.0))
    assert rig.output((30.0, 30.0)) == (PLAIN.kc1 * 30.0, 4.5)
    assert rig.outputs[1].hi == 4.5 and rig.outputs[0].hi == PLAIN.outputs[0].hi


def test_a_pump_moves_no_water_below_its_threshold() -> None:
    rig = CoupledCascade(vmin=1.5)
    assert rig.rhs((0.0, 0.0), (1.4,)) == (0.0, 0.0)
    assert rig.rhs((0.0, 0.0), (5.0,))[0] == pytest.approx(rig.beta1 * 3.5, rel=1e-15)
    op = rig.steady_inputs((15.0, None))
    assert op.u[0] == pytest.approx(PLAIN.steady_inputs((15.0, None)).u[0] + 1.5, rel=1e-12)
    assert rig.steady_state(op.u) == pytest.approx(op.x, rel=1e-9)


@pytest.mark.parametrize(("changes", "message"), [
    ({"spill1": 1.5}, "spill1 must be in [0, 1], got 1.5"),
    ({"vmin": -1.0}, "vmin must be a finite number >= 0 V, got -1.0"),
    ({"ysat2": float("inf")}, "ysat2 must be a finite number >= 0 V"),
    ({"vmin": 22.0}, "vmin must be below vmax = 22 V"),
])
def test_refused_values(changes: dict[str, float], message: str) -> None:
    with pytest.raises(PlantError, match=message.replace("[", r"\[").replace("]", r"\]")):
        PLAIN.with_values(**changes)


def test_par_round_trip_names_the_effects_only_when_on() -> None:
    shipped = PLANT_SETTINGS["coupled-cascade"]
    text = format_par(shipped, _stamp())
    assert "spill1" not in text and "vmin" not in text and "ysat" not in text
    on = parse_par(text.replace("vmax 22.000000\n", "vmax 22.000000\nspill1 0.25\nysat2 4.5\nvmin 0.8\n")).params
    assert on.process_plant() == CoupledCascade(spill1=0.25, ysat2=4.5, vmin=0.8)
    again = format_par(on, _stamp())
    assert "spill1 0.250000\nvmin 0.800000\nysat2 4.500000\n" in again and "ysat1" not in again
    assert parse_par(again).params == on


def _stamp():
    from datetime import datetime

    return datetime(2026, 1, 1)
