"""The model predictive controller, one sample at a time, in plant units.

Each sample: the Kalman filter corrects the state and disturbance estimates with
the measured levels; the targets follow from the references over the horizon (the
announced ones with preview, else the present one held); the QP gives the inputs
and the first one goes out.  A solve that fails (OSQP's status not solved, a
non-finite reading or result, an exception) never raises: the last input applied
is held, clipped to the pump range and the rate limit, and the fault counted.
Solve times are kept for the percentiles.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np

from quadtank_tui.core.mpc.kalman import KalmanFilter
from quadtank_tui.core.mpc.model import MPCModel, build_model
from quadtank_tui.core.mpc.qp import SparseQP, Weights, weights
from quadtank_tui.core.mpc.settings import MPCSettings
from quadtank_tui.core.plants.base import Plant


@dataclass(frozen=True, eq=False)
class MPCDesign:
    """What the MPC runs on: the model, the settings, the weights and the QP size."""

    model: MPCModel
    settings: MPCSettings
    weights: Weights

    @property
    def gain(self) -> np.ndarray:
        """The LQR gain on [x; u_prev] the unconstrained MPC equals (m x (n+m))."""
        return self.weights.K

    def closed_loop_poles(self) -> np.ndarray:
        """Poles (z) of the model under the unconstrained gain: A - B Kx without a rate
        weight, else those of the augmented loop."""
        mdl, K, n, m = self.model, self.weights.K, self.model.n, self.model.m
        if not np.any(self.weights.S):
            M = mdl.A - mdl.B @ K[:, :n]
        else:
            Aa = np.block([[mdl.A, np.zeros((n, m))], [np.zeros((m, n + m))]])
            M = Aa - np.vstack([mdl.B, np.eye(m)]) @ K
        return np.array(sorted(np.linalg.eigvals(M), key=lambda z: (-abs(z), z.imag)))


def design_mpc(plant: Plant, levels: Sequence[float], s: MPCSettings, T: float) -> MPCDesign:
    """The MPC design on `plant` at its operating `levels`, sampled at T s;
    ParameterError names the setting when there is none."""
    model = build_model(plant, levels, s, T)
    return MPCDesign(model, s, weights(model, s))


def percentiles(times: Iterable[float], qs: Sequence[float]) -> tuple[float, ...]:
    """The percentiles `qs` (0..100) of solve times, in their unit; NaN each when
    there are none.  The one place the controller's statistics, the simulations'
    figures and the loop's controller box work them out, so they agree."""
    values = np.fromiter(times, float)
    if not values.size:
        return (float("nan"),) * len(qs)
    return tuple(float(p) for p in np.percentile(values, qs))


@dataclass
class MPCStats:
    """Solves done, failed ones, and each sample's solve time (s): wall clock (what
    the loop waits) and this thread's CPU time (what the solve costs whatever else
    shares the machine)."""

    solves: int = 0
    faults: int = 0
    last_status: str = ""
    times: list[float] = field(default_factory=list)
    cpu_times: list[float] = field(default_factory=list)

    def percentile(self, q: float) -> float:
        return percentiles(self.times, (q,))[0]


@dataclass(frozen=True)
class MPCStep:
    """One sample's result: the pump voltages, whether the solve failed, the slack
    (level limit violation the plan accepts, plant units) and the solve time (s)."""

    u: np.ndarray
    fault: bool
    slack: float
    solve_time: float


class MPC:
    """The MPC in plant units: levels read (measured tanks, plant units), references
    of the tracked tanks (plant units), pump voltages out."""

    def __init__(self, d: MPCDesign) -> None:
        self.design = d
        self.qp = SparseQP(d.model, d.settings, d.weights)
        self.kf = KalmanFilter(d.model)
        self.stats = MPCStats()
        self._u_prev = d.model.u_e.copy()  # deviation 0: the operating point
        self.kf.reset(np.zeros(d.model.n))

    def track(self, levels: Sequence[float] | np.ndarray, u_applied: Sequence[float] | np.ndarray) -> None:
        """Start from the present levels (all tanks, plant units) and the pumps as they
        are: a switch to MPC is bumpless.  The estimate starts at the measured levels
        with the disturbance that makes them a steady state under these pumps, so the
        model's steady input is the one in force and the first move is from it (with a
        zero disturbance the target input would be the operating point's, a jump)."""
        mdl = self.design.model
        n = mdl.n
        y = np.asarray(levels, dtype=float)[list(mdl.measured)] - mdl.x_e[list(mdl.measured)]
        u = np.asarray(u_applied, dtype=float)
        M = np.block([[np.eye(n) - mdl.A, -mdl.Bd], [mdl.Cm, mdl.Cd]])
        rhs = np.concatenate([mdl.B @ (u - mdl.u_e), y])
        sol = np.linalg.lstsq(M, rhs, rcond=None)[0] if np.all(np.isfinite(rhs)) else np.zeros(n + mdl.nd)
        self.kf.reset(sol[:n], sol[n:])
        self._u_prev = u.copy()

    def forget_disturbance(self) -> None:
        """Keep the state estimate, start the disturbance estimate again from zero (the
        controller's Reset)."""
        self.kf.reset(self.kf.estimate[: self.design.model.n])

    def _refs(self, r: np.ndarray) -> np.ndarray:
        """References for steps 0..N (rows), deviations: the preview padded with its
        last value, or the present reference held."""
        N = self.design.settings.horizon
        rr = np.atleast_2d(np.asarray(r, dtype=float))
        if not self.design.settings.preview:
            rr = rr[:1]
        if rr.shape[0] < N + 1:
            rr = np.vstack([rr, np.tile(rr[-1], (N + 1 - rr.shape[0], 1))])
        return rr[: N + 1] - self.design.model.Cz @ self.design.model.x_e

    def step(self, measured: Sequence[float] | np.ndarray, refs: Sequence[float] | np.ndarray) -> MPCStep:
        """The pump voltages for this sample.  `measured`: the measured tanks' levels;
        `refs`: the tracked levels' references now, or one row per future sample
        (row 0 now) when they are known."""
        mdl = self.design.model
        t0, c0 = time.perf_counter(), time.thread_time()
        u_dev: np.ndarray | None = None
        slack = 0.0
        status = ""
        try:
            y = np.asarray(measured, dtype=float) - mdl.x_e[list(mdl.measured)]
            r = self._refs(np.asarray(refs, dtype=float))
            if np.all(np.isfinite(y)) and np.all(np.isfinite(r)):
                x, d = self.kf.correct(y)
                xs, us = mdl.target(d, r)
                q, lo, hi = self.qp.vectors(x, d, xs, us, self._u_prev - mdl.u_e)
                v, status = self.qp.solve(q, lo, hi)
                if v is not None:
                    u_dev = v[self.qp.ui(0)]
                    slack = float(np.max(v[self.qp.si], initial=0.0))
            else:
                self.kf.coast()
                status = "non-finite reading or reference"
        except Exception as exc:  # the loop goes on whatever the solver does: hold and count
            self.kf.coast()
            status = f"{type(exc).__name__}: {exc}"
        dt, cpu = time.perf_counter() - t0, time.thread_time() - c0
        fault = u_dev is None
        u = self._u_prev.copy() if u_dev is None else u_dev + mdl.u_e
        u = self._limit(u)
        if fault:
            self.stats.faults += 1
        self.stats.solves += 1
        self.stats.last_status = status
        self.stats.times.append(dt)
        self.stats.cpu_times.append(cpu)
        self.applied(u)
        return MPCStep(u, fault, slack, dt)

    def _limit(self, u: np.ndarray) -> np.ndarray:
        mdl, s = self.design.model, self.design.settings
        if s.rate_limit > 0:
            du = s.rate_limit * mdl.T
            u = np.clip(u, self._u_prev - du, self._u_prev + du)
        return np.clip(u, mdl.u_lo, mdl.u_hi)

    def applied(self, u: Sequence[float] | np.ndarray) -> None:
        """The input went out (V): the estimator predicts with it, the rate terms start
        from it.  `step` calls it with its own result; the loop calls it again with
        what the pumps really got (an interlock may have held one), which replaces that."""
        u = np.asarray(u, dtype=float)
        self._u_prev = u.copy()
        self.kf.predict(u - self.design.model.u_e)
