"""The nonlinear plant under MPC or under the `.par` file's PI matrix, sampled, for
a reference step on each loop and then a load disturbance (a leak in tank 1): the
comparison `quadtank mpc` prints and benchmarks/mpc.py measures.

The plant is the project's nonlinear model with its faults (core.faults.advance:
adaptive Dormand-Prince over each sample with the pumps held).  The PI matrix runs
in the loop's normalized units (y = sensor V / 10, u = V / full scale) like the
engine; the MPC reads the measured levels and, with preview, the references over
its horizon (the scenario is known in advance, as a wave or a script is).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from quadtank_tui.core import faults as fx
from quadtank_tui.core.controllers.matrix import ControllerMatrix
from quadtank_tui.core.metrics import loop_metrics
from quadtank_tui.core.controllers.mpc.predictive import MPC, percentiles
from quadtank_tui.core.plants.base import Plant

FULL_SCALE_V = 10.0


@dataclass(frozen=True)
class Scenario:
    """References (tracked levels, plant units) from time 0: `r0`, then each
    (time s, loop 0-based, new level); a leak (time s, tank 1-based, area) or None;
    `duration` s."""

    r0: tuple[float, ...]
    steps: tuple[tuple[float, int, float], ...]
    leak: tuple[float, int, float] | None
    duration: float

    def reference(self, t: float) -> np.ndarray:
        r = np.array(self.r0, dtype=float)
        for ts, loop, level in self.steps:
            if t >= ts - 1e-9:
                r[loop] = level
        return r


def holdable(plant: Plant, levels: Sequence[float], margin: float) -> bool:
    """Whether pumps within their range hold the tracked tanks at `levels` with every
    tank at least `margin` x its height below the brim."""
    given: list[float | None] = [None] * len(plant.states)
    for loop, i in enumerate(plant.controlled):
        given[i] = float(levels[loop])
    try:
        op = plant.steady_inputs(given)
    except ValueError:
        return False
    return (all(sig.lo <= v <= sig.hi for v, sig in zip(op.u, plant.inputs))
            and all(x <= st.hi - margin * (st.hi - st.lo) for x, st in zip(op.x, plant.states)))


def standard_scenario(plant: Plant, x_e: Sequence[float], *, step: float = 0.3, phase: float = 300.0,
                      leak: float = 0.15, lead: float = 10.0) -> Scenario:
    """Step each tracked level up (in turn, `phase` s apart, from 10 s), then open a
    leak on tank 1 of `leak` x its outlet; the first step comes at `lead` s (a
    horizon's length, so a preview sees all of it).  The step is `step` x the tank's height,
    or the largest multiple of 5 % of it whose final levels pumps in range hold with
    every tank 10 % below its brim (P+ fills its upper tanks first): large enough to
    saturate a PI tuned near the operating point, small enough to reach."""
    idx = list(plant.controlled)
    r0 = tuple(float(x_e[i]) for i in idx)
    heights = [plant.states[i].hi - plant.states[i].lo for i in idx]
    while step > 0.0 and not holdable(plant, [r + step * h for r, h in zip(r0, heights)], 0.1):
        step = round(step - 0.05 * (1.0 if step > 0.05 else step / 0.05), 6)
    steps = tuple((lead + k * phase, k, r0[k] + step * heights[k]) for k in range(len(idx)))
    outlet = plant.values()[plant.outlet_names[0]] if plant.outlet_names else 0.0
    hole = (lead + len(idx) * phase, 1, leak * outlet) if outlet > 0 else None
    return Scenario(r0, steps, hole, lead + (len(idx) + 1) * phase)


@dataclass(frozen=True)
class Run:
    """Samples k = 0..K-1 at t = k T: levels x (K, n), commanded pumps u (K, m),
    references r (K, loops), faults (failed solves) and solve times (s)."""

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    r: np.ndarray
    faults: int = 0
    solve_times: tuple[float, ...] = ()


def closed_loop(plant: Plant, x0: Sequence[float], scn: Scenario, T: float,
                control: Callable[[float, np.ndarray], np.ndarray]) -> tuple[np.ndarray, ...]:
    """Sample, control, hold the pumps over T, with the scenario's leak; `control`
    takes (t, levels) and returns the pump volts (core.controllers.closed_loop, the
    simulator the design preview runs on too)."""
    from quadtank_tui.core.controllers.closed_loop import simulate

    leak = fx.Faults().on(fx.Fault("leak", scn.leak[1], scn.leak[2])) if scn.leak is not None else None

    def faults(t: float) -> fx.Faults:
        return leak if leak is not None and scn.leak is not None and t >= scn.leak[0] - 1e-9 else fx.Faults()

    K = int(round(scn.duration / T))
    run = simulate(plant, x0, T, K, lambda k, t, x: control(t, x), faults=faults)
    return run.t, run.x, run.u, np.array([scn.reference(t) for t in run.t])


def run_mpc(plant: Plant, mpc: MPC, x0: Sequence[float], scn: Scenario) -> Run:
    """The scenario under the MPC, started bumplessly at x0 with the operating pumps."""
    mdl, s = mpc.design.model, mpc.design.settings
    Tp, N = mpc.design.prediction.T, s.horizon
    mpc.track(x0, mdl.u_e)
    start_faults, start_times = mpc.stats.faults, len(mpc.stats.times)

    def control(t: float, x: np.ndarray) -> np.ndarray:
        refs = np.array([scn.reference(t + j * Tp) for j in range(N + 1)]) if s.preview else scn.reference(t)
        return mpc.step(x[list(mdl.measured)], refs).u

    t, x, u, r = closed_loop(plant, x0, scn, mdl.T, control)
    return Run(t, x, u, r, mpc.stats.faults - start_faults, tuple(mpc.stats.times[start_times:]))


def sensor_gains(plant: Plant) -> np.ndarray:
    """Sensor volts per level unit, tank by tank (every plant's sensors are linear)."""
    n = len(plant.states)
    return np.array([plant.output(np.eye(n)[i])[i] for i in range(n)])


def run_pi(plant: Plant, matrix: ControllerMatrix, x0: Sequence[float], u0: Sequence[float], scn: Scenario) -> Run:
    """The scenario under the PI matrix (channels = the first two tanks and pumps, as
    the loop wires them), its integrators started at the pumps u0."""
    gain = sensor_gains(plant)
    full = np.array([sig.full_scale for sig in plant.inputs])
    idx = list(plant.controlled)
    m = len(plant.inputs)

    def normalized(t: float, x: np.ndarray) -> tuple[tuple[float, float], tuple[float, float]]:
        y = (gain * x / FULL_SCALE_V).tolist() + [0.0, 0.0]
        r = list(y[:2])
        for loop, i in enumerate(idx):
            r[i] = float(gain[i] * scn.reference(t)[loop] / FULL_SCALE_V)
        return (r[0], r[1]), (y[0], y[1])

    r_, y_ = normalized(0.0, np.asarray(x0, dtype=float))
    un = (list(np.asarray(u0, dtype=float) / full) + [0.0, 0.0])[:2]
    matrix.reset()
    matrix.track(r_, y_, (un[0], un[1]))

    def control(t: float, x: np.ndarray) -> np.ndarray:
        r, y = normalized(t, x)
        v = matrix.compute(r, y)
        u = (min(max(v[0], 0.0), 1.0), min(max(v[1], 0.0), 1.0))
        matrix.update(r, y, u)
        return np.array(u[:m]) * full

    t, x, u, r = closed_loop(plant, x0, scn, T=matrix.h, control=control)
    return Run(t, x, u, r)


@dataclass(frozen=True)
class Figures:
    """Per loop: IAE (level unit x s) over the run and over the leak, overshoot (% of
    its step); the seconds some pump sat at a limit; samples with a level outside
    [floor, brim - margin] by more than 0.1 % of the tank's height (a soft limit the
    linear model puts a level on misses by about that); failed solves; solve time
    p50 / p99 (ms, nan for PI)."""

    iae: tuple[float, ...]
    iae_leak: tuple[float, ...]
    overshoot: tuple[float, ...]
    at_limit: float
    violations: int
    faults: int
    p50_ms: float
    p99_ms: float


def figures(plant: Plant, run: Run, scn: Scenario, x_lo: np.ndarray, x_hi: np.ndarray) -> Figures:
    """The comparison's figures of one run."""
    idx = list(plant.controlled)
    T = float(run.t[1] - run.t[0])
    iae, iae_leak, over = [], [], []
    leak_from = scn.leak[0] if scn.leak else scn.duration
    for loop, i in enumerate(idx):
        e = np.abs(run.r[:, loop] - run.x[:, i])
        iae.append(float(np.sum(e) * T))
        iae_leak.append(float(np.sum(e[run.t >= leak_from - 1e-9]) * T))
        ts = next(st for st in scn.steps if st[1] == loop)[0]
        window = (run.t >= ts - T) & (run.t < min([st[0] for st in scn.steps if st[0] > ts] + [leak_from]))
        over.append(loop_metrics(run.t[window], run.x[window, i], run.r[window, loop], min_step=1e-9).overshoot or 0.0)
    lo = np.array([sig.lo for sig in plant.inputs])
    hi = np.array([sig.hi for sig in plant.inputs])
    limited = np.any((run.u <= lo + 1e-6) | (run.u >= hi - 1e-6), axis=1)
    tol = 1e-3 * np.array([st.hi - st.lo for st in plant.states])
    bad = np.any((run.x < x_lo - tol) | (run.x > x_hi + tol), axis=1)
    p50, p99 = percentiles((t * 1e3 for t in run.solve_times), (50, 99))
    return Figures(tuple(iae), tuple(iae_leak), tuple(over), float(np.sum(limited) * T), int(np.sum(bad)),
                   run.faults, p50, p99)
