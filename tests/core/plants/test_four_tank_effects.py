"""The effects a real quadruple tank (Johansson's, Desautel's QTP) and the two-input
rig show (core.plants.effects): an upper tank whose overflow falls in a fraction into
the tank below (beside, on the two-input rig), a sensor that saturates at its range, a
pump that moves no water below a threshold. Off by default, bit for bit the plain
model; in the `.par` only when on."""

from __future__ import annotations

from dataclasses import replace
from datetime import datetime

import pytest

from quadtank_tui.core.plants import johansson as qt
from quadtank_tui.core.parameters import PLANT_SETTINGS, PRESET
from quadtank_tui.core.plants.common import PlantError
from quadtank_tui.core.plants.johansson import P_MINUS, P_PLUS
from quadtank_tui.core.plants import CoupledTITO, DesautelQTP, QuadTank
from quadtank_tui.files.par import ParFileError, format_par, parse_par
from quadtank_tui.files.physical_par import with_fit

STAMP = datetime(2026, 1, 1)
EFFECTS = ("spill3", "spill4", "vmin1", "vmin2", "ysat1", "ysat2", "ysat3", "ysat4",
           "lam1", "lam2", "lam3", "lam4", "off1", "off2", "off3", "off4")


def test_off_by_default_every_method_is_core_plants() -> None:
    p = P_PLUS.params
    rig = QuadTank(p, **{n: 0.0 for n in EFFECTS})
    assert rig == QuadTank(p) and not rig.effects_on and rig.effect_names == EFFECTS
    x, u = (20.0, 7.0, 20.0, 3.0), (9.0, 9.0)
    assert rig.rhs(x, u) == qt.rhs(x, u, p)
    assert rig.advance(x, u, 5.0) == qt.advance(x, u, 5.0, p)
    assert rig.steady_state(u) == qt.steady_state_levels(u, p)
    assert DesautelQTP(spill3=0.0).rhs(x, u) == DesautelQTP().rhs(x, u)


def test_an_upper_tank_overflows_into_the_tank_below_in_the_fitted_fraction() -> None:
    p = P_PLUS.params
    rig = QuadTank(p, spill3=0.5)
    x, u = (5.0, 5.0, 20.0, 5.0), (3.0, 9.0)   # tank 3 at its brim, pump 2 filling it
    plain = qt.rhs(x, u, p)
    excess = (1 - p.gamma2) * p.k2 * 9.0 - qt.outflow(20.0, p.a3, p.g)  # cm^3/s
    assert excess > 0 and plain[2] == 0.0
    got = rig.rhs(x, u)
    assert got[2] == 0.0 and got[1] == plain[1] and got[3] == plain[3]
    assert got[0] == pytest.approx(plain[0] + 0.5 * excess / p.A1, rel=1e-14)
    assert rig.rhs((5.0, 5.0, 19.0, 5.0), u) == pytest.approx(qt.rhs((5.0, 5.0, 19.0, 5.0), u, p), rel=1e-15)
    wide = QuadTank(replace(p, a1=0.15), spill3=0.5)  # at rest: tank 1 passes its share of the excess too
    h = wide.steady_state(u)
    inflow = p.gamma1 * p.k1 * 3.0 + qt.outflow(20.0, p.a3, p.g) + 0.5 * excess
    assert h[2] == 20.0 and qt.outflow(h[0], 0.15, p.g) == pytest.approx(inflow, rel=1e-9)
    x0 = h
    assert wide.advance(x0, u, 50.0) == pytest.approx(x0, abs=1e-6)  # the steady state holds


def test_a_sensor_saturates_and_a_pump_has_a_threshold() -> None:
    rig = QuadTank(P_MINUS.params, ysat2=6.0, vmin1=0.8)
    assert rig.output((10.0, 10.0, 19.0, 19.0)) == (5.0, 5.0, 9.5, 9.5)
    assert rig.output((10.0, 14.0, 5.0, 5.0))[1] == 6.0 and rig.outputs[1].hi == 6.0 and rig.outputs[0].hi == 10.0
    assert rig.rhs((0.0,) * 4, (0.7, 0.0)) == (0.0, 0.0, 0.0, 0.0)
    p = P_MINUS.params
    assert rig.rhs((0.0,) * 4, (3.0, 0.0))[0] == pytest.approx(p.gamma1 * p.k1 * 2.2 / p.A1, rel=1e-15)
    op = rig.steady_inputs((12.4, 12.7))
    plain = QuadTank(p).steady_inputs((12.4, 12.7))
    assert op.u == pytest.approx((plain.u[0] + 0.8, plain.u[1]), rel=1e-12)
    assert rig.steady_state(op.u) == pytest.approx(op.x, rel=1e-9)


def test_the_two_input_rig() -> None:
    plain = CoupledTITO()
    assert CoupledTITO(spill1=0.0, vmin2=0.0, ysat1=0.0) == plain and not plain.effects_on
    rig = CoupledTITO(spill1=0.6, vmin2=0.4, ysat2=5.8)
    x, u = (0.3, 0.15), (6.9, 0.3)   # tank 1 full, pump 2 under its threshold
    q12, q2 = plain.flows(x)
    excess = plain.Gp * 6.9 - q12
    assert rig.rhs(x, u) == (0.0, pytest.approx((q12 + 0.6 * excess - q2) / plain.A2, rel=1e-14))
    assert plain.rhs(x, u)[1] == pytest.approx((q12 + plain.Gp * 0.3 - q2) / plain.A2, rel=1e-14)
    assert rig.output((0.1, 0.2)) == (pytest.approx(3.333), 5.8) and rig.outputs[1].hi == 5.8
    h1, h2 = rig.steady_state((6.9, 0.3))  # tank 1 brims, tank 2 drains its inflow and 60 % of the excess
    q12, drain = rig.flows((h1, h2))
    assert h1 == 0.3 and q12 + 0.6 * (plain.Gp * 6.9 - q12) == pytest.approx(drain, rel=1e-9)


@pytest.mark.parametrize(("plant", "changes", "message"), [
    (QuadTank(), {"spill3": 1.5}, "spill3 must be in [0, 1], got 1.5"),
    (QuadTank(), {"vmin2": 10.0}, "vmin2 must be below the pump's 10 V"),
    (DesautelQTP(), {"ysat4": -1.0}, "ysat4 must be a finite number >= 0 V, got -1.0"),
    (CoupledTITO(), {"vmin1": 7.0}, "vmin1 must be below the pump's 6.94 V"),
    (CoupledTITO(), {"spill2": -0.1}, "spill2 must be in [0, 1]"),
])
def test_refused_values(plant, changes: dict[str, float], message: str) -> None:
    with pytest.raises(PlantError, match=message.replace("[", r"\[").replace("]", r"\]")):
        plant.with_values(**changes)


def test_quadtank_par_names_the_effects_in_a_plant_section_only_when_on() -> None:
    text = format_par(PRESET, STAMP)
    assert "PLANT" not in text and parse_par(text).params.process_plant() == QuadTank(PRESET.quadtank_constants())
    on = parse_par(text + "\nPLANT\nKind quadtank\nysat2 9.5\nspill3 0.4\nvmin1 0\n").params
    assert on.process is None and on.simulation.effects == (("spill3", 0.4), ("ysat2", 9.5))
    assert on.process_plant() == QuadTank(PRESET.quadtank_constants(), spill3=0.4, ysat2=9.5)
    again = format_par(on, STAMP)
    assert again == text + "\nPLANT\nKind quadtank\nspill3 0.400000\nysat2 9.500000\n"
    assert parse_par(again).params == on
    kept = on.with_values({"SIMULATION.Valve1": 0.6}).process_plant()
    assert isinstance(kept, QuadTank) and kept.spill3 == 0.4  # a Setup change keeps them


@pytest.mark.parametrize(("tail", "message"), [
    ("spill3 1.4", "line 165: PLANT.spill3: spill3 must be in [0, 1], got 1.4"),
    ("a1 0.07", "line 165: PLANT.a1: the quadruple tank's values live in SIMULATION"),
    ("vmin1 x", "line 165: PLANT.vmin1: not a number"),
])
def test_quadtank_par_refuses_bad_effects(tail: str, message: str) -> None:
    text = format_par(PRESET, STAMP) + "\nPLANT\nKind quadtank\n" + tail + "\n"
    assert text.count("\n") == 165
    with pytest.raises(ParFileError, match=message.replace("[", r"\[").replace("]", r"\]")):
        parse_par(text)


@pytest.mark.parametrize("kind", ["desautel-qtp", "coupled-tito"])
def test_other_plants_par_round_trip(kind: str) -> None:
    shipped = PLANT_SETTINGS[kind]
    text = format_par(shipped, STAMP)
    assert "spill" not in text and "vmin" not in text and "ysat" not in text
    key = "spill3" if kind == "desautel-qtp" else "spill1"
    on = parse_par(text + f"ysat2 4.5\n{key} 0.25\n").params
    assert on.process_plant() == shipped.process_plant().with_values(ysat2=4.5, **{key: 0.25})
    again = format_par(on, STAMP)
    assert f"{key} 0.250000\n" in again and "ysat2 4.500000\n" in again and "ysat1" not in again
    assert parse_par(again).params == on


def test_a_fitted_effect_goes_into_a_new_plant_section_of_a_quadtank_file() -> None:
    text = format_par(PRESET, STAMP)
    fitted = QuadTank(PRESET.quadtank_constants(), spill3=0.5, ysat1=6.5)
    new = with_fit(text, "p.par", fitted, {"spill3": "+- 1e-09 (1 standard error); was 0"})
    assert new.startswith(text.rstrip("\n")) and new.endswith(
        "\n\nPLANT\nKind quadtank\nspill3 0.500000\n% spill3 fitted: +- 1e-09 (1 standard error); was 0\n"
        "ysat1 6.500000\n")
    assert parse_par(new).params.process_plant() == fitted


def test_the_simulator_runs_a_quadruple_tank_with_an_effect_through_the_plant() -> None:
    from quadtank_tui.engine.sim import SimBackend

    rig = QuadTank(P_MINUS.params, ysat1=5.5)
    sim = SimBackend.for_plant(rig, (14.0, 10.0, 2.0, 2.0))
    assert sim.plant == rig and sim.read_levels()[:2] == (0.55, 0.5)
    plain = SimBackend.for_plant(QuadTank(P_MINUS.params), (14.0, 10.0, 2.0, 2.0))
    assert plain.params == P_MINUS.params and plain.read_levels()[0] == 0.7  # the plain path, as before
