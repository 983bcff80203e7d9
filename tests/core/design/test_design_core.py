"""Design rules, their error messages, and the accuracy of the delayed simulation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quadtank_tui.core.design.pid_tuning import PIDTuning, DesignError
from quadtank_tui.core.design.evaluate import evaluate
from quadtank_tui.core.design.expr import parse_model
from quadtank_tui.core.design.frequency import is_stable, margins
from quadtank_tui.core.design.lambda_tuning import first_order, lambda_for_tau, lambda_pi
from quadtank_tui.core.design.optimize import pi_ms, pid_ms
from quadtank_tui.core.design.simulate import step_response

P1 = "1.6592*exp(-2.4*s)/(1.07*s+1)^3"
P2 = "-0.00641*exp(-44.37*s)/s"
P3 = "0.3104*(39.251*s+1)/(14.28*s+1)^2*exp(-4.44*s)"
P4 = "-0.00651*exp(-2*s)/s"


def test_first_order_of_process_1_is_andersson_s() -> None:
    """His printed lambda model (line 464: 1.6637 e^-3.60s/(2.13s+1)) is a step fit;
    the same fit of the third-order model gives T and L within 0.5 %."""
    fo = first_order(parse_model(P1))
    assert fo.how == "step-response fit"
    assert fo.T == pytest.approx(2.13, rel=0.005) and fo.L == pytest.approx(3.60, rel=0.005)
    assert fo.K == pytest.approx(1.6592)


def test_first_order_of_an_integrator_with_lag_is_its_ramp_asymptote() -> None:
    fo = first_order(parse_model("-0.00652*exp(-2*s)/(s*(49.33*s+1))"))
    assert (fo.integrating, fo.K, fo.L, fo.how) == (True, -0.00652, pytest.approx(51.33), "ramp asymptote")


def test_lambda_from_tau_is_andersson_s_rows() -> None:
    fo = first_order(parse_model("1.6637*exp(-3.60*s)/(2.13*s+1)"))
    assert [lambda_for_tau(fo, t) for t in (1, 2, 3)] == pytest.approx([3.6, 7.2, 10.8])
    c = lambda_pi(fo, 8.0)
    assert (c.Kc, c.Ti, c.Td) == (pytest.approx(2.13 / (1.6637 * 11.6)), 2.13, 0.0)


@pytest.mark.parametrize("text, words", [
    ("1/(s-1)", "pole in the right half-plane"),
    ("exp(-s)/s^2", "one integrator at most"),
    ("s/(s+1)^2", "zero static gain"),
])
def test_lambda_refuses_what_it_cannot_tune(text: str, words: str) -> None:
    with pytest.raises(DesignError, match=words):
        first_order(parse_model(text))


def test_lambda_must_be_positive() -> None:
    with pytest.raises(DesignError, match="lambda must be a time > 0"):
        lambda_pi(first_order(parse_model(P4)), -1.0)


@pytest.mark.parametrize("ms", [1.0, 0.8, math.nan])
def test_ms_must_exceed_one(ms: float) -> None:
    with pytest.raises(DesignError, match="Ms must be a number > 1"):
        pi_ms(parse_model(P1), ms)
    with pytest.raises(DesignError, match="Ms must be a number > 1"):
        pid_ms(parse_model(P1), ms)


@pytest.mark.parametrize("text, ms", [(P1, 1.2), (P1, 1.4), (P1, 1.6), (P2, 1.4), (P3, 1.6), (P4, 1.2)])
def test_pid_rule_meets_ms_and_beats_pi(text: str, ms: float) -> None:
    """The program's PID (max ki, Td <= Ti/4) meets Ms on its model and integrates
    the load away faster than the PI_opt of the same Ms."""
    g = parse_model(text)
    pid, pi = pid_ms(g, ms), pi_ms(g, ms)
    assert pid.Td > 0.0 and pid.Td <= pid.Ti / 4 * (1 + 1e-6)
    assert margins(pid.loop(g)).Ms <= ms + 0.002
    assert margins(pi.loop(g)).Ms == pytest.approx(ms, abs=0.002)
    assert pid.ki / pi.ki > 1.2
    assert math.copysign(1.0, pid.Kc) == math.copysign(1.0, g.static_gain)


def test_unstable_loop_is_reported() -> None:
    g = parse_model(P1)
    c = PIDTuning(2.0, 1.0)  # far too much gain for a 2.4 s delay
    assert not is_stable(c.loop(g))
    ev = evaluate(c, g)
    assert not ev.stable and math.isinf(ev.Ms)
    assert is_stable(PIDTuning(0.1682, 2.13).loop(g))
    # wrong sign on a negative-gain process: positive feedback
    assert not is_stable(PIDTuning(33.63, 14).loop(parse_model(P4)))


@pytest.mark.parametrize("text, c", [(P1, PIDTuning(0.349, 2.62, 1.23)), (P4, PIDTuning(-21.7, 13.5))])
def test_simulation_is_converged_and_integrates_the_load_away(text: str, c: PIDTuning) -> None:
    """IE = d / ki exactly for a PI/PID after a load step d; halving h moves IAE < 0.05 %."""
    g = parse_model(text)
    d = 10.0
    fine = step_response(g, c, d=d, horizon=400.0, h=g.delay / 40)
    coarse = step_response(g, c, d=d, horizon=400.0, h=g.delay / 20)
    ie = np.trapezoid(fine.e, fine.t)
    assert abs(ie) == pytest.approx(d / abs(c.ki), rel=1e-4)
    iae = [np.trapezoid(np.abs(r.e), r.t) for r in (fine, coarse)]
    assert iae[1] == pytest.approx(iae[0], rel=5e-4)
    assert fine.u[-1] == pytest.approx(-d, rel=1e-6)


def test_delay_is_exact_in_the_simulation() -> None:
    """Open-loop view: with Kc tiny, y stays exactly 0 until the delay has passed."""
    g = parse_model("exp(-3*s)/(s+1)")
    resp = step_response(g, PIDTuning(1e-9, 1e9), d=1.0, horizon=10.0, h=0.01)
    assert np.all(resp.y[resp.t < 3.0 - 1e-9] == 0.0)
    k = np.searchsorted(resp.t, 5.0)
    assert resp.y[k] == pytest.approx(1.0 - math.exp(-2.0), rel=1e-6)


def test_controller_frequency_response_is_one_value_per_frequency() -> None:
    """A P controller (Ti = inf) answered Kc alone, not an array: mypy found it."""
    w = np.array([0.01, 0.1, 1.0])
    p = PIDTuning(2.0, math.inf).freqresp(w)
    assert p.shape == w.shape
    np.testing.assert_array_equal(p, [2.0, 2.0, 2.0])
    pi = PIDTuning(2.0, 10.0).freqresp(w)
    np.testing.assert_allclose(pi, 2.0 * (1.0 + 1.0 / (10.0 * 1j * w)), rtol=1e-15)
