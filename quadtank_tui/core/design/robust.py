"""A designed pair tried over what the model does not know: N quadruple-tank plants
drawn about the nominal one, each under the pair on the batch path (core.batch: the
engine's PID and flow law, all N at once), a reference step of 0.1 on each loop in
turn from each plant's own steady state at the operating levels.

The spread is what a student needs before Apply: overshoot, settling and IAE of
each step, their median and worst over the N plants, and how many plants go
unstable, limit-cycle or cannot be held at the operating levels by pumps in range.

Pure numbers: the draws come from a seeded generator, so a spread is reproducible.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from quadtank_tui.core.batch import pi_batch
from quadtank_tui.core.design.pid_tuning import PIDTuning
from quadtank_tui.core.controllers.pid import PIDParams
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.plants.johansson import PlantParams

STEP = 0.1  # normalized, as the preview's
BAND = 0.02  # of the step: the settling band


@dataclass(frozen=True)
class Spread:
    """Uniform relative spreads of the outlets' areas and the pumps' gains, and an
    absolute one of the valve splits (the stated spread of a preset)."""

    outlets: float = 0.10
    pumps: float = 0.10
    valves: float = 0.05

    def describe(self) -> str:
        return (f"+-{self.outlets:.0%} outlets, +-{self.pumps:.0%} pumps, +-{self.valves:g} valve splits "
                "(uniform, each independently)")


def draw_plants(nominal: PlantParams, n: int, spread: Spread = Spread(), seed: int = 0) -> list[PlantParams]:
    """`n` plants about `nominal`, the first of them the nominal one itself."""
    rng = np.random.default_rng(seed)
    out = [nominal]
    for _ in range(n - 1):
        o = 1.0 + spread.outlets * rng.uniform(-1.0, 1.0, 4)
        k = 1.0 + spread.pumps * rng.uniform(-1.0, 1.0, 2)
        g = spread.valves * rng.uniform(-1.0, 1.0, 2)
        out.append(replace(nominal, a1=nominal.a1 * o[0], a2=nominal.a2 * o[1], a3=nominal.a3 * o[2],
                           a4=nominal.a4 * o[3], k1=nominal.k1 * k[0], k2=nominal.k2 * k[1],
                           gamma1=min(1.0, max(0.0, nominal.gamma1 + g[0])),
                           gamma2=min(1.0, max(0.0, nominal.gamma2 + g[1]))))
    return out


def steady_state(p: PlantParams, h1: float, h2: float) -> tuple[np.ndarray, np.ndarray] | None:
    """Levels (4, cm) and pump volts (2) holding tanks 1 and 2 at h1, h2 (cm); None
    when no pumps within 0..10 V do, or an upper tank would pass its brim."""
    q1, q2 = p.a1 * math.sqrt(2 * p.g * h1), p.a2 * math.sqrt(2 * p.g * h2)
    # q1 = g1 k1 v1 + (1 - g2) k2 v2; q2 = (1 - g1) k1 v1 + g2 k2 v2
    M = np.array([[p.gamma1 * p.k1, (1 - p.gamma2) * p.k2], [(1 - p.gamma1) * p.k1, p.gamma2 * p.k2]])
    try:
        v = np.linalg.solve(M, [q1, q2])
    except np.linalg.LinAlgError:
        return None
    if np.any(v < 0.0) or np.any(v > FULL_SCALE_V):
        return None
    q3, q4 = (1 - p.gamma2) * p.k2 * v[1], (1 - p.gamma1) * p.k1 * v[0]
    h3, h4 = (q3 / p.a3) ** 2 / (2 * p.g), (q4 / p.a4) ** 2 / (2 * p.g)
    if max(h1, h2, h3, h4) >= p.hmax:
        return None
    return np.array([h1, h2, h3, h4]), v


@dataclass(frozen=True)
class StepSpread:
    """One loop's step over the plants that could be held: each plant's figures
    (settling nan where it did not settle) and its verdict."""

    loop: int
    overshoot: np.ndarray  # %
    settling: np.ndarray  # s
    iae: np.ndarray  # normalized x s
    unstable: np.ndarray  # bool
    limit_cycle: np.ndarray  # bool
    window: float  # s

    def summary(self) -> dict[str, float | None]:
        def med(a: np.ndarray) -> float:
            return float(np.median(a))
        settle = np.where(np.isnan(self.settling), np.inf, self.settling)
        worst_settle = float(np.max(settle))
        return {"overshoot_median": med(self.overshoot), "overshoot_worst": float(np.max(self.overshoot)),
                "settling_median": float(np.median(settle)) if np.isfinite(np.median(settle)) else None,
                "settling_worst": worst_settle if math.isfinite(worst_settle) else None,
                "IAE_median": med(self.iae), "IAE_worst": float(np.max(self.iae)),
                "unstable": int(self.unstable.sum()), "limit_cycles": int(self.limit_cycle.sum()),
                "not_settled": int(np.isnan(self.settling).sum())}


@dataclass(frozen=True)
class Robustness:
    """The pair over N plants: each loop's step spread, and what it was drawn from."""

    n: int
    held: int  # plants whose pumps can hold the operating levels (the others are not run)
    steps: tuple[StepSpread, ...]
    source: str
    h: float

    @property
    def warnings(self) -> list[str]:
        out = []
        for s in self.steps:
            sm = s.summary()
            if sm["unstable"]:
                out.append(f"loop {s.loop}: {sm['unstable']} of {self.held} plants of the spread go unstable")
            if sm["limit_cycles"]:
                out.append(f"loop {s.loop}: {sm['limit_cycles']} of {self.held} plants of the spread limit-cycle")
        if self.held < self.n:
            out.append(f"{self.n - self.held} of {self.n} plants of the spread cannot be held at the operating "
                       "levels by pumps in 0..10 V (not simulated)")
        return out

    def to_dict(self) -> dict[str, object]:
        return {"n": self.n, "held": self.held, "source": self.source, "sampling_time": self.h,
                "warnings": self.warnings,
                "steps": [{"loop": s.loop, "window": s.window, **s.summary()} for s in self.steps]}


def format_robustness(rb: Robustness) -> str:
    """The spread as lines: median and worst of each figure, per loop."""
    window = max(s.window for s in rb.steps)
    lines = [f"over {rb.n} plants ({rb.source}), {window:.0f} s each step, sampled at {rb.h:g} s, "
             "on the batch path: median / worst"]
    for s in rb.steps:
        sm = s.summary()
        late = f"> {s.window:.0f} s"
        med = late if sm["settling_median"] is None else f"{sm['settling_median']:.0f} s"
        worst = (f"{late} ({sm['not_settled']} not settled)" if sm["settling_worst"] is None
                 else f"{sm['settling_worst']:.0f} s")
        lines.append(f"  r{s.loop}: overshoot {sm['overshoot_median']:.1f} / {sm['overshoot_worst']:.1f} %, "
                     f"settling {med} / {worst}, IAE {sm['IAE_median']:.3f} / {sm['IAE_worst']:.3f}")
    lines.extend(f"WARNING: {w}" for w in rb.warnings)
    return "\n".join(lines)


def _pid_params(c: PIDTuning, tr: float) -> PIDParams:
    integral = math.isfinite(c.Ti) and c.Ti < 1e6
    return PIDParams(K=c.Kc, Ti=c.Ti if integral else 1e6, Td=c.Td, Tr=tr, N=c.N, b=c.b,
                     integral=integral, derivative=c.Td > 0.0)


def _verdicts(t: np.ndarray, e: np.ndarray, other: np.ndarray, u: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per experiment (rows): settling of the stepped loop's error e (nan: not
    settled), unstable, limit-cycling.  Unstable: not finite; either loop's error
    (e, or the other loop's `other`) still growing in swing from the third quarter to
    the last; or a pump (u: rows x samples x 2) pinned at a limit over the last
    quarter with either error above half the step (the saturated end of an unstable
    loop).  A limit cycle: not settled, a steady swing above the band."""
    band = BAND * STEP
    K = e.shape[1]
    outside = np.abs(e) > band
    last = np.where(outside.any(axis=1), K - 1 - np.argmax(outside[:, ::-1], axis=1), -1)
    settled = last < K - 1
    settling = np.where(settled, t[np.minimum(last + 1, K - 1)], np.nan)
    q = max(1, K // 4)
    finite = np.all(np.isfinite(e), axis=1) & np.all(np.isfinite(other), axis=1)
    growing = np.zeros(e.shape[0], dtype=bool)
    for err in (e, other):
        s3, s4 = np.ptp(err[:, -2 * q:-q], axis=1), np.ptp(err[:, -q:], axis=1)
        growing |= (s4 > 1.2 * s3) & (s4 > band)
    pinned = np.any(np.all((u[:, -q:] <= 1e-9) | (u[:, -q:] >= 1.0 - 1e-9), axis=1), axis=1)
    off = (np.abs(e[:, -1]) > 0.5 * STEP) | (np.abs(other[:, -1]) > 0.5 * STEP)
    unstable = ~finite | growing | pinned & off
    swing = np.ptp(e[:, -q:], axis=1)
    cycle = ~settled & ~unstable & (swing > 2 * band) & (swing > 0.8 * np.ptp(e[:, -2 * q:-q], axis=1))
    return settling, unstable, cycle


def robustness(plants: Sequence[PlantParams], levels: tuple[float, float], pair: Sequence[PIDTuning], h: float,
               window: float, *, tr: Sequence[float] = (1.0, 1.0), source: str = "") -> Robustness:
    """Each plant from its steady state at `levels` (tanks 1 and 2, cm): a STEP on
    loop 1, and (another run of the same plant, from rest) a STEP on loop 2, all in
    one batch of `window` s."""
    starts = [steady_state(p, *levels) for p in plants]
    ok = [i for i, s in enumerate(starts) if s is not None]
    ps = [plants[i] for i in ok]
    x0 = np.array([starts[i][0] for i in ok])  # type: ignore[index]
    v0 = np.array([starts[i][1] for i in ok])  # type: ignore[index]
    pid = (_pid_params(pair[0], tr[0]), _pid_params(pair[1], tr[1]))
    n = len(ps)
    K = int(math.ceil(window / h)) + 1
    kc = np.array([p.kc for p in ps])
    y0 = kc[:, None] * x0[:, :2] / FULL_SCALE_V
    r = np.vstack([y0, y0])
    r[:n, 0] += STEP
    r[n:, 1] += STEP
    refs = np.repeat(r[:, None, :], K, axis=1)
    run = pi_batch(ps + ps, np.vstack([x0, x0]), np.vstack([v0, v0]) / FULL_SCALE_V, refs, pid, h)
    t = np.arange(K) * h
    steps = []
    for loop in (1, 2):
        rows = slice(0, n) if loop == 1 else slice(n, 2 * n)
        e = r[rows, loop - 1][:, None] - run.y[rows, :, loop - 1]
        other = r[rows, 2 - loop][:, None] - run.y[rows, :, 2 - loop]
        overshoot = np.maximum(0.0, np.max(-e, axis=1) / STEP * 100.0)
        iae = np.sum(np.abs(e), axis=1) * h
        settling, unstable, cycle = _verdicts(t, e, other, run.u[rows])
        steps.append(StepSpread(loop, overshoot, settling, iae, unstable, cycle, float(t[-1])))
    return Robustness(len(plants), n, tuple(steps), source, h)
