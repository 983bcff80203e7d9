"""A designed pair of PIDs tried on the nonlinear model of the plant in use before
it is applied: a reference step on each loop in turn, predicted (the linear sampled
design) and simulated (the plant's nonlinear equations) side by side.

Pure numbers (no engine, no files), so the CLI, the TUI's worker and the tests
call the same function and it runs in a fraction of a second: the loop is what
the engine runs in Automatic with a decentralized PID (elements 11 and 22,
core.pid at the sampling time, normalized signals, pumps clipped to 0..1 as
core.matrix.saturate does, the anti-windup time Tr of the parameters), started
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

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.controller import PID
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

    @property
    def warnings(self) -> list[str]:
        return [w for s in self.steps for w in s.warnings]

    def to_dict(self) -> dict[str, object]:
        return {"sampling_time": self.h, "warnings": self.warnings, "steps": [
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


def _predicted(G: Sequence[Sequence[DelayTF]], pair: Sequence[PID], h: float, loop: int, r0: Sequence[float],
               u0: Sequence[float], samples: int, tr: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
    pids = [running_pid(c, h, tr) for c in pair]
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


#: the window when no settling time is known, and its bounds, s
DEFAULT_WINDOW = 600.0
WINDOW_RANGE = (120.0, 3000.0)


#: samples per step at most (the nonlinear plant costs 0.1-0.3 ms a sample): 3000 s at 0.1 s,
#: enough for P+'s slow loop 2 (1100 s to settle)
MAX_SAMPLES = 30000


def window_for(settling_times: Sequence[float | None], h: float) -> float:
    """Four times the slower loop's designed (single-loop, unlimited) settling time
    within WINDOW_RANGE and MAX_SAMPLES samples of h: the other loop's coupling slows
    the steps (about 2x at P-); a step that needs longer is reported not settled."""
    if not settling_times or any(t is None for t in settling_times):
        w = DEFAULT_WINDOW
    else:
        w = min(WINDOW_RANGE[1], max(WINDOW_RANGE[0], 4.0 * max(t for t in settling_times if t is not None)))
    return min(w, MAX_SAMPLES * h)


def format_preview(pv: Preview) -> str:
    """Predicted (linear sampled) and simulated (nonlinear plant) figures of each step."""
    lines = [f"preview on the nonlinear simulator, sampled at {pv.h:g} s, pumps 0..10 V: step 0.1 on each loop"]
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


def preview(plant: Plant, levels: Sequence[float], inputs: Sequence[float], pair: Sequence[PID], h: float, *,
            window: float, model: Sequence[Sequence[DelayTF]] | None = None,
            tr: Sequence[float] = (TR_DEFAULT, TR_DEFAULT),
            progress: Callable[[float], None] | None = None) -> Preview:
    """A STEP on each loop in turn from `levels` (all tanks, the plant's unit) and
    `inputs` (pump volts), `window` s each, sampled at h; `model` (1x1 or 2x2,
    normalized) adds the predicted curves; `progress` hears the share done (0..1)."""
    p = len(pair)
    ctrl = list(plant.controlled)[:p]
    scale = [s.full_scale for s in plant.inputs][:p]
    brims = [s.hi for s in plant.states]
    n = int(math.ceil(window / h)) + 1
    t = np.arange(n) * h
    steps = []
    for loop in range(1, p + 1):
        x = tuple(float(v) for v in levels)
        y0 = [plant.output(x)[c] / FULL_SCALE_V for c in ctrl]
        u0 = [min(1.0, max(0.0, inputs[i] / scale[i])) for i in range(p)]
        pids = [running_pid(c, h, tr[i]) for i, c in enumerate(pair)]
        for i in range(p):  # bumpless: the integrator holds the input at the start
            pids[i].track(y0[i], y0[i], u0[i])
        r = list(y0)
        r[loop - 1] += STEP
        ys = np.zeros((n, p))
        us = np.zeros((n, p))
        brim = 0.0
        volts = [0.0] * len(plant.inputs)
        for k in range(n):
            out = plant.output(x)
            yk = [out[c] / FULL_SCALE_V for c in ctrl]
            for i in range(p):
                v = pids[i].compute(r[i], yk[i])
                ui = min(1.0, max(0.0, v))
                pids[i].update(r[i], yk[i], ui)
                us[k, i] = ui
                volts[i] = ui * scale[i]
            ys[k] = yk
            if any(xi >= b - 1e-6 for xi, b in zip(x, brims)):
                brim += h
            x = plant.advance(x, volts, h)
            if progress is not None and k % 200 == 0:
                progress(((loop - 1) + k / n) / p)
        i = loop - 1
        other = ys[:, 1 - i] if p == 2 else None
        rr = np.full(n, r[i])
        sim = _figures(t, ys[:, i], rr, other, us, i, h)
        pred_y, pred = None, None
        if model is not None:
            py, pu, _ = _predicted(model, pair, h, loop, y0, u0, n, tr[0])
            pred_y = py[:, i]
            pred = _figures(t, py[:, i], rr, py[:, 1 - i] if p == 2 else None, pu, i, h)
        steps.append(PreviewStep(loop, t, ys[:, i], pred_y, us, sim, pred, brim, window))
    return Preview(tuple(steps), h)
