"""The sampled loop (issue 23): the ZOH model with its dead time, core.controllers.pid's own
discretization, the exact discrete-time Ms design, the limit check, the sampled 2x2
check, and the identified-model case that limit-cycled on the rig at Ts = 1 s."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quadtank_tui.core.design.pid_tuning import PIDTuning
from quadtank_tui.core.design.evaluate import evaluate
from quadtank_tui.core.design.expr import parse_model
from quadtank_tui.core.design.mimo import design_2x2, model_in_use, slowest_pole
from quadtank_tui.core.design.optimize import pi_ms, pid_ms
from quadtank_tui.core.design.sampled import closed_loop_poles, sample
from quadtank_tui.core.design.sampled_eval import evaluate_sampled, running_pid, simulate
from quadtank_tui.core.design.table import candidates, suggested
from quadtank_tui.core.parameters import PRESET

#: the identified G11 of the issue: a PRBS at Ts = 1 s on P-, 99.4 % fit
IDENTIFIED = parse_model("2.5882*exp(-0.041*s)/(62.14*s+1)")
ANDERSSON_1 = parse_model("1.6592*exp(-2.4*s)/(1.07*s+1)^3")


def test_the_continuous_design_is_unstable_sampled_at_1s_and_the_sampled_one_holds() -> None:
    """Before: Kc 165.2, Ti 0.2753 s, crossover 7.62 rad/s (above Nyquist, 3.14 rad/s
    at 1 s); sampled at 1 s that loop is unstable.  Designed for the sampled loop:
    Ms 1.4 of the sampled loop, the crossover well below Nyquist."""
    old = pi_ms(IDENTIFIED, 1.4)
    assert old.Kc == pytest.approx(165.2, rel=1e-3) and old.Ti == pytest.approx(0.2753, rel=1e-3)
    assert not evaluate(old, IDENTIFIED, h=1.0).stable
    c = pi_ms(IDENTIFIED, 1.4, h=1.0)
    assert c.Kc == pytest.approx(14.91, rel=2e-3) and c.Ti == pytest.approx(3.750, rel=2e-3)
    ev = evaluate(c, IDENTIFIED, h=1.0)
    assert ev.stable and ev.Ms == pytest.approx(1.4, abs=2e-3) and ev.sampling_time == 1.0
    assert ev.crossover < 0.25 * math.pi  # a fifth of the Nyquist frequency


@pytest.mark.parametrize("h", [0.1, 0.5])
def test_ms_designs_meet_their_ms_on_the_sampled_loop(h: float) -> None:
    for design in (pi_ms, pid_ms):
        c = design(ANDERSSON_1, 1.4, h=h)
        assert evaluate(c, ANDERSSON_1, h=h).Ms == pytest.approx(1.4, abs=5e-3), design.__name__


def test_a_fast_sampled_loop_gives_the_continuous_figures() -> None:
    g, c = parse_model("exp(-0.2*s)/(s+1)^2"), PIDTuning(1.2, 1.5)
    cont, samp = evaluate(c, g), evaluate(c, g, h=0.01)
    for name in ("Ms", "crossover", "IAE", "Emax"):
        assert getattr(samp, name) == pytest.approx(getattr(cont, name), rel=5e-3), name
    # the hold and the forward-difference integral lag about w h/2 each at crossover
    lag = math.degrees(cont.crossover * 0.01)
    assert cont.phase_margin_deg - 1.5 * lag < samp.phase_margin_deg < cont.phase_margin_deg - 0.5 * lag


def test_the_sampled_model_has_the_dead_time_of_whole_samples_and_a_fraction() -> None:
    """e^(-2.35 s)/(s+1) at h = 1: two whole samples and 0.35 s; the step response at
    the samples is the continuous one, exactly: 1 - e^-(t - 2.35) for t >= 2.35."""
    m = sample(parse_model("exp(-2.35*s)/(s+1)"), 1.0)
    assert (m.d, m.tau) == (2, pytest.approx(0.35))
    x, y = np.zeros(m.A.shape[0]), []
    for _ in range(8):
        y.append(float(m.C @ x))
        x = m.A @ x + m.B
    t = np.arange(8.0)
    np.testing.assert_allclose(y, np.where(t >= 2.35, 1.0 - np.exp(-(t - 2.35)), 0.0), atol=1e-12)


def _core_pid_loop(m, c: PIDTuning, *, r: float = 0.0, d: float = 0.0, samples: int,
                   limits: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    pid = running_pid(c, m.h)
    x, y, u = np.zeros(m.A.shape[0]), [], []
    for _ in range(samples):
        yk = float(m.C @ x)
        v = pid.compute(r, yk)
        uk = min(limits[1], max(limits[0], v))
        pid.update(r, yk, uk)
        y.append(yk)
        u.append(uk)
        x = m.A @ x + m.B * (uk + d)
    return np.array(y), np.array(u)


@pytest.mark.parametrize("c", [PIDTuning(14.9, 3.75), PIDTuning(28.23, 1.676, 0.04114)])
def test_the_simulation_is_core_pid_sample_by_sample(c: PIDTuning) -> None:
    """Limits, anti-windup and the derivative filter included: the same numbers as
    stepping core.controllers.pid.PID itself."""
    m = sample(IDENTIFIED, 0.5)
    for kw in ({"r": 0.1}, {"d": -0.1}, {"d": 0.3}):
        got = simulate(m, c, samples=600, limits=(-0.3, 0.7), **kw)
        y, u = _core_pid_loop(m, c, samples=600, limits=(-0.3, 0.7), **kw)
        np.testing.assert_allclose(got.y, y, atol=1e-12)
        np.testing.assert_allclose(got.u, u, atol=1e-12)
    assert np.any(u == -0.3)  # the last load needs more than the pump has: the limit held


def test_the_table_marks_saturating_rows_and_never_suggests_them() -> None:
    rows = candidates(IDENTIFIED, h=1.0, u0=0.3)
    marked = {r.label for r in rows if r.problem}
    assert "PI Ms 1.6" in marked  # a pump limit for more than a fifth of its settling
    best = suggested(rows)
    assert best is not None and rows[best].problem is None
    assert rows[best].label == "PI Ms 1.4"


def test_a_chattering_candidate_is_marked() -> None:
    """Kc = 40 puts a closed-loop pole near z = -0.67 (a - Kc b, a = e^(-1/62.14), b = K (1 - a)):
    stable, but the pump reverses every sample."""
    ev = evaluate_sampled(PIDTuning(40.0, 50.0), IDENTIFIED, 1.0, u0=0.5)
    assert ev.evaluation.stable and ev.limits is not None and ev.limits.chatters
    assert ev.limits.problem is not None and "chatters" in ev.limits.problem


def test_the_2x2_check_is_the_sampled_loops() -> None:
    """The pair of the issue (designed in continuous time, Ts = 1 s in force): x said
    stable; sampled at 1 s it is not.  The sampled design of P- is."""
    G = model_in_use(PRESET)
    pair = (PIDTuning(129.8, 0.349), PIDTuning(146.4, 0.412))
    assert slowest_pole(G, *pair) < 0.0  # the continuous-time check
    assert slowest_pole(G, *pair, h=1.0) > 0.0
    chk = design_2x2(G, "pi-ms", h=1.0)
    assert chk.stable and chk.sampling_time == 1.0
    assert max(abs(closed_loop_poles(G[0][0], chk.loops[0].controller, 1.0))) < 1.0
