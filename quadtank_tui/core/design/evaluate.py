"""Evaluate a PI/PID on a model: Andersson's figures (003_... section 4.3).

Conventions that make his section 4.4 tables come out (control.md): the
controller is evaluated on the model given (his *simulation* model, whatever
model it was designed on); the load disturbance is a step at the process input
of size 10/K (self-regulating) or 10 (integrating), and IAE, Emax and the control
overshoot max|u|/|u_final| - 1 are measured after it; the PID derivative is
filtered, Td s/(1 + s Td/10), on the measurement (pid_tuning.PIDTuning).
"""

from __future__ import annotations

import math

import numpy as np

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.evaluation import Evaluation, load_size
from quadtank_tui.core.design.pid_tuning import PIDTuning
from quadtank_tui.core.design.frequency import Margins, frequency_grid, margins
from quadtank_tui.core.design.simulate import STEPS_PER_RAD, Response, step_response
from quadtank_tui.core.metrics import loop_metrics

#: the load response is simulated until its last tenth stays below this share of Emax.
SETTLED = 1e-4


def time_step(g: DelayTF, m: Margins) -> float:
    """Step h: 1/STEPS_PER_RAD of 1/wc, dividing the delay (see simulate)."""
    h = 1.0 / (STEPS_PER_RAD * m.crossover) if math.isfinite(m.crossover) else 0.01
    if g.delay >= 0.5 * h:
        h = g.delay / math.ceil(g.delay / h)
    # a delay below half a step is not resolved at this step (simulate rounds it to
    # none); dividing it would shrink h to it: an identified 2e-5 s delay asked for
    # 9e7 steps
    return h


def settled_response(g: DelayTF, c: PIDTuning, m: Margins, *, r: float = 0.0, d: float = 0.0) -> Response:
    """Simulate long enough for the error to die out (doubling the horizon)."""
    h = time_step(g, m)
    horizon = 30.0 / m.crossover + 5.0 * (c.Ti if math.isfinite(c.Ti) else 0.0)
    for _ in range(6):
        resp = step_response(g, c, r=r, d=d, horizon=horizon, h=h)
        e = np.abs(resp.e)
        tail = e[int(0.9 * len(e)):]
        if tail.max() <= SETTLED * max(e.max(), 1e-300):
            break
        horizon *= 2.0
        h = max(h, horizon / 100_000)
        if g.delay >= 0.5 * h:
            h = g.delay / max(1, math.floor(g.delay / h))
    return resp


def evaluate(c: PIDTuning, g: DelayTF, w: np.ndarray | None = None, *, setpoint: bool = True,
             h: float = 0.0) -> Evaluation:
    """All figures of controller `c` on process model `g` (setpoint=False: skip the
    setpoint step, which Andersson's table does not show; its figures are then nan).
    h > 0: the figures of the loop sampled at h with core.controllers.pid's PID
    (core.design.sampled_eval); h = 0: the continuous-time loop."""
    if h > 0.0:
        from quadtank_tui.core.design.sampled_eval import evaluate_sampled

        return evaluate_sampled(c, g, h, u0=None, setpoint=setpoint).evaluation
    m = margins(c.loop(g), frequency_grid(c.loop(g)) if w is None else w)
    nan = math.nan
    if not m.stable:
        return Evaluation(math.inf, m.phase_margin_deg, m.gain_margin, m.delay_margin,
                          m.crossover, nan, nan, nan, load_size(g), nan, None, False)
    d = load_size(g)
    load = settled_response(g, c, m, d=d)
    e = np.abs(load.e)
    iae = float(np.trapezoid(e, load.t))
    u_final = -d  # integral action cancels the load exactly
    u_over = float(np.max(np.abs(load.u)) / abs(u_final) - 1.0)
    overshoot, settling = nan, None
    if setpoint:
        sp = settled_response(g, c, m, r=1.0)
        lm = loop_metrics(np.concatenate([[-1e-9], sp.t]), np.concatenate([[0.0], sp.y]),
                          np.concatenate([[0.0], np.ones_like(sp.y)]))
        overshoot, settling = float(lm.overshoot or 0.0), lm.settling_time
    return Evaluation(m.Ms, m.phase_margin_deg, m.gain_margin, m.delay_margin, m.crossover,
                      iae, float(e.max()), max(u_over, 0.0), d, overshoot, settling, True)
