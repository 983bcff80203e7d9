"""A designed pair of PIDs tried on the nonlinear model of the plant in use before
it is applied: a reference step on each loop in turn, predicted (the linear sampled
design) and simulated (the plant's nonlinear equations) side by side.

Pure numbers (no engine, no files), so the CLI, the TUI's worker and the tests
call the same function; the nonlinear loop runs on the one closed-loop simulator
(core.controllers.closed_loop) and is what the engine runs in Automatic with a decentralized PID (elements 11 and 22,
core.controllers.pid at the sampling time, normalized signals, pumps clipped to 0..1 as
core.controllers.matrix.saturate does, the anti-windup time Tr of the parameters), started
bumpless from the given levels and inputs (references at the measured levels,
integrators holding the inputs, as the Manual -> Automatic switch does).  The
rig's DAQ interlock stops a pump whose tank reaches its brim: the simulation
reports the time any tank spends at its brim instead.

Verdicts: `unstable` (the output leaves the band and grows), `limit_cycle` (the
pump reverses on most samples, or the output still oscillates at the end), and
`saturates` (a pump at a limit for more than a fifth of the window).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from quadtank_tui.core.controllers.closed_loop import simulate
from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.pid_tuning import PIDTuning
from quadtank_tui.core.design.sampled import closed_loop, sample
from quadtank_tui.core.design.sampled_eval import (
    CHATTER_SHARE, SATURATION_SHARE, TR_DEFAULT, propagate_from, reversals, running_pid,
)
from quadtank_tui.core.metrics import loop_metrics
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.plants.base import Plant

STEP = 0.1  # normalized: 1 V of sensor, 10 % of the range

Matrix = tuple[tuple[DelayTF, DelayTF], tuple[DelayTF, DelayTF]]


@dataclass(frozen=True)
class Figures:
    """A step's figures on the stepped loop (and the other loop's peak)."""

    overshoot_pct: float
    settling: float | None  # s, 2 % band; None: not settled in the window
    iae: float
    other_peak: float  # largest |y_other - its start|, normalized
    at_limit: float  # s any pump spent at 0 or full scale
    reversals: float  # share of moving samples the stepped loop's pump reversed on

    def to_dict(self) -> dict[str, float | None]:
        return {"overshoot_pct": self.overshoot_pct, "settling_time": self.settling, "IAE": self.iae,
                "other_peak": self.other_peak, "time_at_pump_limit": self.at_limit,
                "input_reversals": self.reversals}


@dataclass(frozen=True)
class PreviewStep:
    loop: int
    t: np.ndarray
    simulated: np.ndarray  # y of the stepped loop, normalized
    predicted: np.ndarray | None  # the linear sampled design's y, normalized
    u: np.ndarray  # the pumps, normalized, samples x inputs
    sim: Figures
    pred: Figures | None
    brim_time: float  # s any tank spent at its brim (the rig's interlock would trip)
    window: float

    @property
    def unstable(self) -> bool:
        e = np.abs(self.simulated - self.simulated[-1])
        return bool(self.sim.settling is None and np.abs(self.simulated[-1] - self.simulated[0]) > 5 * STEP
                    ) or not bool(np.all(np.isfinite(self.simulated))) or bool(e.max() > 1.0)

    @property
    def limit_cycle(self) -> bool:
        return self.sim.reversals > CHATTER_SHARE or (self.sim.settling is None and not self.unstable)

    @property
    def saturates(self) -> bool:
        return self.sim.at_limit > SATURATION_SHARE * self.window

    @property
    def warnings(self) -> list[str]:
        out = []
        if self.unstable:
            out.append(f"loop {self.loop}: the simulated plant is unstable")
        elif self.limit_cycle:
            out.append(f"loop {self.loop}: the simulated plant limit-cycles (pump reverses on "
                       f"{self.sim.reversals:.0%} of the samples)" if self.sim.reversals > CHATTER_SHARE
                       else f"loop {self.loop}: the simulated step does not settle in {self.window:.0f} s")
        if self.saturates:
            out.append(f"loop {self.loop}: a pump is at its limit {self.sim.at_limit:.0f} s of {self.window:.0f} s")
        if self.brim_time > 0.0:
            out.append(f"loop {self.loop}: a tank is at its brim {self.brim_time:.0f} s (the rig's interlock trips)")
        return out


@dataclass(frozen=True)
class Preview:
    steps: tuple[PreviewStep, ...]
    h: float
    span: Horizon | None = None

    @property
    def warnings(self) -> list[str]:
        return [w for s in self.steps for w in s.warnings]

    def to_dict(self) -> dict[str, object]:
        span = None if self.span is None else {"cap": self.span.cap, "hold": self.span.hold,
                                                "time_constant": self.span.tau, "fixed": self.span.fixed}
        return {"sampling_time": self.h, "warnings": self.warnings, "horizon": span, "steps": [
            {"loop": s.loop, "window": s.window, "simulated": s.sim.to_dict(),
             "predicted": None if s.pred is None else s.pred.to_dict(), "brim_time": s.brim_time,
             "unstable": s.unstable, "limit_cycle": s.limit_cycle, "saturates": s.saturates}
            for s in self.steps]}


def _figures(t: np.ndarray, y: np.ndarray, r: np.ndarray, other: np.ndarray | None, u: np.ndarray,
             pump: int, h: float) -> Figures:
    lm = loop_metrics(np.concatenate([[t[0] - h], t]), np.concatenate([[y[0]], y]),
                      np.concatenate([[r[0] - STEP * np.sign(r[-1] - r[0] or 1.0)], r]))
    at = np.any((u <= 1e-9) | (u >= 1.0 - 1e-9), axis=1)
    peak = 0.0 if other is None else float(np.max(np.abs(other - other[0])))
    return Figures(float(lm.overshoot or 0.0), lm.settling_time, lm.iae, peak, float(at.sum()) * h,
                   reversals(u[:, pump], STEP))


def _predicted(G: Sequence[Sequence[DelayTF]], pair: Sequence[PIDTuning], h: float, loop: int, r0: Sequence[float],
               u0: Sequence[float], samples: int, tr: Sequence[float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The linear sampled loop (deviations about the start), pumps limited: y of
    each loop and the pumps, for a STEP on `loop`."""
    p = len(pair)
    models = [[sample(G[i][j], h) for j in range(p)] for i in range(p)]
    if all(m.Dd == 0.0 for row in models for m in row):  # first the unlimited loop, in blocks
        A, Bu, Bc, Y, U = closed_loop(models, list(pair), h)
        w_u = np.array([c.Kc * c.b * (STEP if i == loop - 1 else 0.0) for i, c in enumerate(pair)])
        w_c = np.array([(c.Kc * h / c.Ti if math.isfinite(c.Ti) else 0.0) * (STEP if i == loop - 1 else 0.0)
                        for i, c in enumerate(pair)])
        yu = propagate_from(A, Bu @ w_u + Bc @ w_c, np.vstack([Y, U]), np.zeros(A.shape[0]), samples)
        y_lin, u_lin = yu[:, :p], yu[:, p:] + w_u[None, :]
        if np.all((u_lin >= -np.asarray(u0)[None, :]) & (u_lin <= 1.0 - np.asarray(u0)[None, :])):
            steps = np.zeros(p)
            steps[loop - 1] = STEP
            return y_lin + np.asarray(r0)[None, :], u_lin + np.asarray(u0)[None, :], steps  # never limited: exact
    xs = [[np.zeros(m.A.shape[0]) for m in row] for row in models]
    pids = [running_pid(c, h, tr[i]) for i, c in enumerate(pair)]
    y = np.zeros((samples, p))
    u = np.zeros((samples, p))
    r = [0.0] * p
    r[loop - 1] = STEP
    for k in range(samples):
        yk = [sum(float(models[i][j].C @ xs[i][j]) for j in range(p)) for i in range(p)]
        uk = []
        for i in range(p):
            v = pids[i].compute(r[i], yk[i])
            ui = min(1.0 - u0[i], max(-u0[i], v))
            pids[i].update(r[i], yk[i], ui)
            uk.append(ui)
        for i in range(p):
            for j in range(p):
                m = models[i][j]
                xs[i][j] = m.A @ xs[i][j] + m.B * uk[j]
        y[k], u[k] = yk, uk
    return y + np.asarray(r0)[None, :], u + np.asarray(u0)[None, :], np.asarray(r)


#: samples per step at most (the nonlinear plant costs 0.1-0.3 ms a sample): 3000 s at 0.1 s,
#: above the cap of P+'s slow loop 2 (10 x 275 s)
MAX_SAMPLES = 30000


def format_preview(pv: Preview) -> str:
    """Predicted (linear sampled) and simulated (nonlinear plant) figures of each step."""
    lines = [f"preview on the nonlinear simulator, sampled at {pv.h:g} s, pumps 0..10 V: step 0.1 on each loop"]
    if pv.span is not None:
        lines.append(f"  {pv.span.describe()}; ran " + ", ".join(f"r{s.loop} {s.window:.0f} s" for s in pv.steps))
    for s in pv.steps:
        for name, f in (("predicted", s.pred), ("simulated", s.sim)):
            if f is None:
                continue
            settle = "not settled" if f.settling is None else f"{f.settling:.0f} s"
            lines.append(f"  r{s.loop} {name:9}: overshoot {f.overshoot_pct:.1f} %, settling (2 %) {settle}, "
                         f"IAE {f.iae:.3f}, " + (f"peak in y{3 - s.loop} {f.other_peak:.4f}, "
                                                 if s.u.shape[1] == 2 else "") + "at a pump limit "
                         f"{f.at_limit:.0f} s, reversals {f.reversals:.0%}")
    lines.extend(f"WARNING: {w}" for w in pv.warnings)
    return "\n".join(lines)


def time_constant(plant: Plant, levels: Sequence[float], inputs: Sequence[float],
                  model: Sequence[Sequence[DelayTF]] | None, pair: Sequence[PIDTuning], h: float) -> float:
    """The slowest time constant the steps must wait for, s: the larger of the plant's
    slowest open-loop one at the start (its linearization) and the designed loop's
    slowest closed-loop one (the sampled linear loop on `model` with `pair`), when
    `model` is given and that loop is stable."""
    lin = plant.linearize(list(levels), list(inputs))
    rates = -np.linalg.eigvals(lin.A).real
    rates = rates[rates > 1e-12]
    tau = float(1.0 / rates.min()) if rates.size else 0.0
    if model is not None:
        from quadtank_tui.core.design.sampled import closed_loop_matrix, slowest_rate

        p = len(pair)
        models = [[sample(model[i][j], h) for j in range(p)] for i in range(p)]
        rate = slowest_rate(np.linalg.eigvals(closed_loop_matrix(models, list(pair), h)), h)
        if rate < 0.0:
            tau = max(tau, -1.0 / rate)
    if not math.isfinite(tau) or tau <= 0.0:
        raise ValueError("no time constant to size the preview by (the plant does not respond)")
    return tau


#: the preview runs at most this many slowest time constants (time_constant) per step
CAP_TIME_CONSTANTS = 10.0


@dataclass(frozen=True)
class Horizon:
    """How long each step runs: until the stepped output has stayed in its 2 % band
    for `hold` s after it settled, at most `cap` s; `fixed`: exactly `cap` s."""

    cap: float
    hold: float
    tau: float  # the slowest time constant the cap is CAP_TIME_CONSTANTS of, s
    fixed: bool = False

    def describe(self) -> str:
        if self.fixed:
            return f"each step {self.cap:.0f} s"
        return (f"each step until it settles and holds {self.hold:.0f} s, at most {self.cap:.0f} s "
                f"({CAP_TIME_CONSTANTS:g} x the slowest time constant, {self.tau:.0f} s)")


def horizon(tau: float, h: float, window: float | None = None) -> Horizon:
    """The horizon of a preview with slowest time constant `tau` (s) at sampling time
    h: a given `window` runs fixed; else CAP_TIME_CONSTANTS tau (within MAX_SAMPLES
    samples), each step held one tau in its band before it counts as settled."""
    if window is not None:
        return Horizon(min(window, MAX_SAMPLES * h), 0.0, tau, fixed=True)
    return Horizon(min(CAP_TIME_CONSTANTS * tau, MAX_SAMPLES * h), tau, tau)


def _settled(t: np.ndarray, y: np.ndarray, r: float, y_before: float, hold: float) -> bool:
    """The stepped output has been in its 2 % band for `hold` s up to t[-1]."""
    lm = loop_metrics(np.concatenate([[t[0] - (t[1] - t[0] if t.size > 1 else 1.0)], t]),
                      np.concatenate([[y_before], y]), np.concatenate([[y_before], np.full(t.size, r)]))
    return lm.settling_time is not None and t[-1] - t[0] - lm.settling_time >= hold


def preview(plant: Plant, levels: Sequence[float], inputs: Sequence[float], pair: Sequence[PIDTuning], h: float, *,
            window: float | None = None, model: Sequence[Sequence[DelayTF]] | None = None,
            tr: Sequence[float] = (TR_DEFAULT, TR_DEFAULT), span: Horizon | None = None,
            progress: Callable[[float], None] | None = None) -> Preview:
    """A STEP on each loop in turn from `levels` (all tanks, the plant's unit) and
    `inputs` (pump volts), sampled at h; `model` (1x1 or 2x2, normalized) adds the
    predicted curves; `progress` hears the share done (0..1).

    Each step runs `window` s when given, else until it settles (`span`, by default
    horizon(time_constant(...))): the TUI and the CLI call this with the same start
    and get the same run, to the sample."""
    if span is None:
        span = horizon(time_constant(plant, levels, inputs, model, pair, h), h, window)
    p = len(pair)
    ctrl = list(plant.controlled)[:p]
    scale = [s.full_scale for s in plant.inputs][:p]
    brims = [s.hi for s in plant.states]
    cap = int(math.ceil(span.cap / h)) + 1
    chunk = max(1, int(span.hold / h / 4)) if not span.fixed else cap
    steps = []
    for loop in range(1, p + 1):
        y0 = [plant.output(tuple(float(v) for v in levels))[c] / FULL_SCALE_V for c in ctrl]
        u0 = [min(1.0, max(0.0, inputs[i] / scale[i])) for i in range(p)]
        pids = [running_pid(c, h, tr[i]) for i, c in enumerate(pair)]
        for i in range(p):  # bumpless: the integrator holds the input at the start
            pids[i].track(y0[i], y0[i], u0[i])
        r = list(y0)
        r[loop - 1] += STEP
        ys = np.zeros((cap, p))
        us = np.zeros((cap, p))
        t_all = np.arange(cap) * h
        volts = [0.0] * len(plant.inputs)

        def control(k: int, t: float, x: np.ndarray) -> list[float]:
            out = plant.output(tuple(x))
            yk = [out[c] / FULL_SCALE_V for c in ctrl]
            for i in range(p):
                v = pids[i].compute(r[i], yk[i])
                ui = min(1.0, max(0.0, v))
                pids[i].update(r[i], yk[i], ui)
                us[k, i] = ui
                volts[i] = ui * scale[i]
            ys[k] = yk
            if progress is not None and k % 200 == 0:
                progress(((loop - 1) + k / cap) / p)
            return list(volts)

        def settled(k: int) -> bool:
            return (not span.fixed and (k + 1) % chunk == 0
                    and _settled(t_all[:k + 1], ys[:k + 1, loop - 1], r[loop - 1], y0[loop - 1], span.hold))

        run = simulate(plant, levels, h, cap, control, stop=settled)
        n = len(run.t)
        brim = h * float(np.sum(np.any(run.x >= np.asarray(brims)[None, :] - 1e-6, axis=1)))
        t, ys, us = t_all[:n], ys[:n], us[:n]
        window_run = float(t[-1])
        i = loop - 1
        other = ys[:, 1 - i] if p == 2 else None
        rr = np.full(n, r[i])
        sim = _figures(t, ys[:, i], rr, other, us, i, h)
        pred_y, pred = None, None
        if model is not None:
            py, pu, _ = _predicted(model, pair, h, loop, y0, u0, n, tr)
            pred_y = py[:, i]
            pred = _figures(t, py[:, i], rr, py[:, 1 - i] if p == 2 else None, pu, i, h)
        steps.append(PreviewStep(loop, t, ys[:, i], pred_y, us, sim, pred, brim, window_run))
    return Preview(tuple(steps), h, span)
