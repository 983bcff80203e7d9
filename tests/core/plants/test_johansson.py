"""Plant parameters, Setup relations, steady states and disturbances (issue 2)."""

from __future__ import annotations

import dataclasses
import math

import pytest

from quadtank_tui.core.plants.common import PlantError, SteadyStateError
from quadtank_tui.core.plants.johansson import (
    H_FILM, level_for_outflow, outflow, P_MINUS, P_PLUS, PlantParams, add_water, advance,
    area_from_diameter, diameter_from_area, levels_to_normalized, normalized_to_levels,
    outlet_from_time_constant, rhs, steady_state_inputs, steady_state_levels, time_constant,
)


def test_paper_table_constants() -> None:
    p = PlantParams()
    assert (p.A1, p.A2, p.A3, p.A4) == (28.0, 32.0, 28.0, 32.0)
    assert (p.a1, p.a2, p.a3, p.a4) == (0.071, 0.057, 0.071, 0.057)
    assert (p.kc, p.g, p.hmax) == (0.5, 981.0, 20.0)
    assert (P_MINUS.params.k1, P_MINUS.params.k2) == (3.33, 3.35)
    assert (P_MINUS.params.gamma1, P_MINUS.params.gamma2) == (0.70, 0.60)
    assert (P_PLUS.params.k1, P_PLUS.params.k2) == (3.14, 3.29)
    assert (P_PLUS.params.gamma1, P_PLUS.params.gamma2) == (0.43, 0.34)
    assert P_MINUS.op.x == (12.4, 12.7, 1.8, 1.4) and P_MINUS.op.u == (3.0, 3.0)
    assert P_PLUS.op.x == (12.6, 13.0, 4.8, 4.9) and P_PLUS.op.u == (3.15, 3.15)


@pytest.mark.parametrize(
    "changes, field",
    [({"A1": 0.0}, "A1"), ({"gamma2": 1.2}, "gamma2"), ({"k1": -1.0}, "k1"),
     ({"a3": 30.0}, "a3"), ({"hmax": float("nan")}, "hmax")],
)
def test_invalid_params_name_the_field(changes: dict, field: str) -> None:
    with pytest.raises(PlantError, match=field):
        PlantParams(**changes)


def test_normalized_units() -> None:
    """product.md: y = 0.62 is 6.2 V from the sensor, i.e. 12.4 cm at kc = 0.5."""
    p = PlantParams()
    assert levels_to_normalized((12.4,), p)[0] == pytest.approx(0.62)
    assert normalized_to_levels((1.0,), p)[0] == pytest.approx(20.0)


def test_setup_relations_round_trip() -> None:
    """Thesis Figure 33/39: Tank 1 with diameter 5.93 cm, op. point 0.62 shows 62.16 s.

    The thesis's outlet was slightly different from the paper's 0.071 cm^2; from its
    diameter and time constant the relation gives a = 0.0706 cm^2.
    """
    A = area_from_diameter(5.93)
    assert A == pytest.approx(27.618, abs=1e-3)
    assert diameter_from_area(A) == pytest.approx(5.93)
    h0 = 12.4
    a = outlet_from_time_constant(A, 62.16, h0)
    assert a == pytest.approx(0.07064, abs=1e-5)
    assert time_constant(A, a, h0) == pytest.approx(62.16)


def test_valve_change_keeps_everything_else() -> None:
    p = P_MINUS.params
    q = p.with_valves(gamma1=0.43)
    assert q.gamma1 == 0.43 and q.gamma2 == p.gamma2
    assert (q.A1, q.a1, q.k1, q.k2, q.kc) == (p.A1, p.a1, p.k1, p.k2, p.kc)


def test_steady_state_levels_match_hand_formula() -> None:
    """control.md: P- levels for the table's 3.00 V are 12.26, 12.78, 1.63, 1.41 cm."""
    h = steady_state_levels(P_MINUS.op.u, P_MINUS.params)
    assert h == pytest.approx((12.263, 12.783, 1.634, 1.409), abs=1e-3)
    assert rhs(h, tuple(P_MINUS.op.u), P_MINUS.params) == pytest.approx((0, 0, 0, 0), abs=1e-12)


def test_steady_state_inputs_inverts_levels() -> None:
    p = P_MINUS.params
    op = steady_state_inputs(12.4, 12.7, p)
    h = steady_state_levels(op.u, p)
    assert h[0] == pytest.approx(12.4) and h[1] == pytest.approx(12.7)
    # The paper's rounded table is not exactly a steady state: holding 12.4/12.7 cm
    # needs 3.05/2.96 V and gives upper levels 1.59/1.46 cm (table: 3.00 V, 1.8/1.4 cm).
    assert op.u == pytest.approx((3.0486, 2.9612), abs=1e-4)
    assert op.x[2:] == pytest.approx((1.5919, 1.4551), abs=1e-4)


def test_steady_state_inputs_singular_valves_refused() -> None:
    p = P_MINUS.params.with_valves(0.5, 0.5)
    with pytest.raises(SteadyStateError, match="gamma1 \\+ gamma2 = 1"):
        steady_state_inputs(10.0, 10.0, p)


def test_steady_state_inputs_refuses_negative_pump() -> None:
    with pytest.raises(SteadyStateError, match="cannot run backwards"):
        steady_state_inputs(2.0, 15.0, P_MINUS.params)


def test_steady_state_with_overflowing_upper_tank() -> None:
    """A brim-full upper tank stays at hmax; only its outlet flow reaches the tank below."""
    p = PlantParams(gamma1=0.1, gamma2=0.1)
    h = steady_state_levels((10.0, 10.0), p)
    assert h[2] == h[3] == p.hmax
    h_sim = tuple(P_MINUS.op.x)
    for _ in range(40):
        h_sim = advance(h_sim, (10.0, 10.0), 100.0, p)
    assert h_sim == pytest.approx(h, abs=1e-6)


def test_add_water_disturbance_spills_and_never_goes_negative() -> None:
    p = PlantParams()
    h = (10.0, 10.0, 2.0, 2.0)
    assert add_water(h, 3, 1.5, p) == (10.0, 10.0, 3.5, 2.0)
    assert add_water(h, 1, 50.0, p)[0] == p.hmax
    assert add_water(h, 2, -50.0, p)[1] == 0.0
    with pytest.raises(PlantError, match="tank must be 1..4"):
        add_water(h, 5, 1.0, p)


def test_cross_section_change_while_running_speeds_up_the_tank() -> None:
    """An object in tank 1 halves its free cross-section: the level rises ~twice as fast."""
    p = P_MINUS.params
    narrow = p.with_tank(1, area=14.0)
    h0 = P_MINUS.op.x
    wide_after = advance(h0, (6.0, 3.0), 10.0, p)
    narrow_after = advance(h0, (6.0, 3.0), 10.0, narrow)
    assert narrow_after[0] - h0[0] > 1.8 * (wide_after[0] - h0[0])


def test_negative_voltage_is_no_flow() -> None:
    p = PlantParams()
    assert rhs((0, 0, 0, 0), (-5.0, -5.0), p) == (0.0, 0.0, 0.0, 0.0)


def test_step_rejects_bad_dt() -> None:
    with pytest.raises(PlantError):
        advance((1, 1, 1, 1), (1, 1), -1.0, PlantParams())
    with pytest.raises(PlantError):
        advance((1, 1, 1, 1), (1, 1), math.inf, PlantParams())


def test_film_outflow_is_c1_continuous_and_invertible() -> None:
    """Below H_FILM the outflow blends to 0 with Torricelli's value and slope at H_FILM."""
    a, g, d = 0.071, 981.0, H_FILM
    eps = 1e-9
    torricelli = lambda h: a * math.sqrt(2 * g * h)  # noqa: E731
    assert outflow(d - eps, a, g) == pytest.approx(torricelli(d), rel=1e-6)
    slope_below = (outflow(d - eps, a, g) - outflow(d - 2 * eps, a, g)) / eps
    slope_above = (torricelli(d + 2 * eps) - torricelli(d + eps)) / eps
    assert slope_below == pytest.approx(slope_above, rel=1e-3)
    assert outflow(0.0, a, g) == 0.0 and outflow(-1.0, a, g) == 0.0
    assert outflow(12.4, a, g) == torricelli(12.4)  # the paper's law above the film
    for h in (0.0, 1e-4, 0.002, 0.0049, 0.005, 0.3, 12.4):
        assert level_for_outflow(outflow(h, a, g), a, g) == pytest.approx(h, abs=1e-12)


@pytest.mark.parametrize("volts, dt", [((5.0, 6.0), 0.05), ((12.0, 12.0), 0.05), ((0.0, 0.0), 0.05), ((5.0, 6.0), 3.0)])
def test_a_step_from_where_the_last_one_ended_is_the_step_from_those_levels(volts: tuple[float, float],
                                                                            dt: float) -> None:
    # advance starts from its last end (the flows and the slope there, First Same
    # As Last) when given the tuple it returned with the same plant and inputs; a
    # copy of the levels and of the plant takes the long way. Bit for bit the same, every step:
    # filling to the brim, draining to empty, sub-steps within one call, and the
    # inputs changing every third step (nothing carried over then).
    p = P_MINUS.params
    carried = [(1.0, 2.0, 0.0, 19.9)]
    for k in range(400):
        carried.append(advance(carried[-1], volts if k % 3 else (volts[1], volts[0]), dt, p))
    fresh = [(1.0, 2.0, 0.0, 19.9)]
    for k in range(400):  # each step with a copy of the levels and of the plant (equal constants, another object)
        fresh.append(advance(tuple(list(fresh[-1])), volts if k % 3 else (volts[1], volts[0]), dt,
                             dataclasses.replace(p)))
    assert carried == fresh
    assert len(set(carried)) > 100
