"""The model predictive controller, one sample at a time, in plant units.

Each sample: the Kalman filter corrects the state and disturbance estimates with
the measured levels; the targets follow from the references over the horizon (the
announced ones with preview, else the present one held); the QP gives the inputs
and the first one goes out.

The prediction may run on a coarser grid than the loop (the `Step` setting, a
whole number k of sampling times): the QP's model is the plant sampled at k T, its
planned input is held over each step (move blocking), so N steps look N k T s
ahead at the cost of N.  The Kalman filter and the solve still run every sample on
the loop's model: the first move is re-planned each sample with the newest reading.
Practitioners do this where the process is slow against the sampling time (here the
P+ tank's inverse response lasts a minute while the lab samples at 0.1 s): the
alternative, N k samples at T, costs k times the variables and solve time.  A solve that fails (OSQP's status not solved, a
non-finite reading or result, an exception) never raises: the last input applied
is held, clipped to the pump range and the rate limit, and the fault counted.
Solve times are kept for the percentiles.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np

from quadtank_tui.core.controllers.mpc.kalman import KalmanFilter
from quadtank_tui.core.controllers.mpc.model import MPCModel, build_model
from quadtank_tui.core.controllers.mpc.qp import SparseQP, Weights, weights
from quadtank_tui.core.controllers.mpc.settings import MPCSettings
from quadtank_tui.core.plants.base import Plant


@dataclass(frozen=True, eq=False)
class MPCDesign:
    """What the MPC runs on: the model at the loop's sampling time (the estimator's),
    the model at the prediction step (the QP's; the same one when the step is one
    sample), the settings and the weights (on the prediction model)."""

    model: MPCModel
    settings: MPCSettings
    weights: Weights
    prediction: MPCModel

    @property
    def step_samples(self) -> int:
        """Sampling times per prediction step."""
        return int(round(self.prediction.T / self.model.T))

    @property
    def gain(self) -> np.ndarray:
        """The LQR gain on [x; u_prev] the unconstrained MPC equals (m x (n+m)), at the
        prediction step."""
        return self.weights.K

    def closed_loop_poles(self) -> np.ndarray:
        """Poles (z, at the prediction step) of the prediction model under the
        unconstrained gain: A - B Kx without a rate weight, else those of the augmented
        loop."""
        mdl, K, n, m = self.prediction, self.weights.K, self.prediction.n, self.prediction.m
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
    pred = model.resampled(s.step_samples(T))
    return MPCDesign(model, s, weights(pred, s), pred)


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
        self.qp = SparseQP(d.prediction, d.settings, d.weights, first_dt=d.model.T)
        self.kf = KalmanFilter(d.model)
        self.stats = MPCStats()
        self._u_prev = d.model.u_e.copy()  # deviation 0: the operating point
        self._restart = False  # the next step starts bumpless from its own reading (track)
        self.kf.reset(np.zeros(d.model.n))

    def track(self, levels: Sequence[float] | np.ndarray, u_applied: Sequence[float] | np.ndarray, *,
              moving: bool = False) -> None:
        """Start from the present levels (all tanks, plant units) and the pumps as they
        are, so a switch to MPC is bumpless; the next :meth:`step` reads the next sample.

        The estimate is the measured levels with the disturbance that makes them a
        steady state under these pumps: the model's steady input is then the one in
        force (with a zero disturbance the target input would be the operating
        point's, a jump).  That is enough in Manual or on a plant at rest on its
        reference.  `moving` (a switch in Automatic, the levels maybe still on their
        way to the references): the MPC's own answer to the error would jump
        (measured 0.49 of full scale 5 s after a 2-cm step with RateWeight 0), so the
        next step starts from the estimate whose unconstrained first move, against
        that sample's reading and references, is the input in force; the Kalman
        filter then moves it to what the readings say, and the input with it, at its
        own pace."""
        mdl = self.design.model
        y = np.asarray(levels, dtype=float)[list(mdl.measured)] - mdl.x_e[list(mdl.measured)]
        du = np.asarray(u_applied, dtype=float) - mdl.u_e
        sol = self._steady(y, du)
        self.kf.reset(sol[: mdl.n], sol[mdl.n:])
        self.kf.predict(du)
        self._u_prev = du + mdl.u_e
        self._restart = moving

    def _steady(self, y: np.ndarray, du: np.ndarray) -> np.ndarray:
        """[x; d] (deviations) reading the measured levels y, at rest under du."""
        mdl, n = self.design.model, self.design.model.n
        M = np.block([[np.eye(n) - mdl.A, -mdl.Bd], [mdl.Cm, mdl.Cd]])
        rhs = np.concatenate([mdl.B @ du, y])
        return np.linalg.lstsq(M, rhs, rcond=None)[0] if np.all(np.isfinite(rhs)) else np.zeros(n + mdl.nd)

    def _bumpless(self, y: np.ndarray, du: np.ndarray, r: np.ndarray) -> np.ndarray:
        """The estimate [x; d] (deviations) that reads the levels y and whose
        unconstrained first move towards the references r (rows 0..N) is the input in
        force du: the steady one, with the difference put into the input disturbances
        (what a PI's integrator holds; moving the states or the level offsets instead
        puts the upper tanks where the readings say they are not, and the plan against
        their limits).  The steady one when no estimate does that."""
        mdl, pred, n = self.design.model, self.design.prediction, self.design.model.n
        steady = self._steady(y, du)

        def first_move(z: np.ndarray) -> np.ndarray:
            x, d = z[:n], z[n:]
            xs, us = pred.target(d, r)
            q, lo, _ = self.qp.vectors(x, d, xs, us, du)
            return self.qp.unconstrained_move(q, lo)

        b = first_move(steady)
        J = np.column_stack([first_move(steady + e) - b for e in np.eye(n + mdl.nd)])
        E = np.vstack([np.hstack([mdl.Cm, mdl.Cd]), J])
        f = np.concatenate([np.zeros(len(y)), du - b])  # steady already reads y
        # the price of a change: states and level offsets per tank height, input
        # disturbances a thousandth of that per pump range
        cost = np.concatenate([1.0 / mdl.y_scale, 1e3 / mdl.u_scale if mdl.disturbance == "input" else [],
                               np.full(mdl.nd - (mdl.m if mdl.disturbance == "input" else 0),
                                       1.0 / mdl.y_scale.max())])
        v = np.linalg.lstsq(E / cost, f, rcond=None)[0]
        z = steady + v / cost
        if not np.all(np.isfinite(z)) or np.linalg.norm(E @ (z - steady) - f) > 1e-6 * (1.0 + np.linalg.norm(f)):
            return steady
        return z

    def forget_disturbance(self) -> None:
        """Keep the state estimate, start the disturbance estimate again from zero (the
        controller's Reset)."""
        self.kf.reset(self.kf.estimate[: self.design.model.n])

    def _refs(self, r: np.ndarray) -> np.ndarray:
        """References for prediction steps 0..N (rows), deviations: the preview padded
        with its last value, or the present reference held."""
        N = self.design.settings.horizon
        rr = np.atleast_2d(np.asarray(r, dtype=float))
        if not self.design.settings.preview:
            rr = rr[:1]
        if rr.shape[0] < N + 1:
            rr = np.vstack([rr, np.tile(rr[-1], (N + 1 - rr.shape[0], 1))])
        return rr[: N + 1] - self.design.model.Cz @ self.design.model.x_e

    def step(self, measured: Sequence[float] | np.ndarray, refs: Sequence[float] | np.ndarray) -> MPCStep:
        """The pump voltages for this sample.  `measured`: the measured tanks' levels;
        `refs`: the tracked levels' references now, or, when they are known, one row
        per prediction step (row j at j k T s from now, j = 0..N)."""
        mdl = self.design.model
        t0, c0 = time.perf_counter(), time.thread_time()
        u_dev: np.ndarray | None = None
        slack = 0.0
        status = ""
        try:
            y = np.asarray(measured, dtype=float) - mdl.x_e[list(mdl.measured)]
            r = self._refs(np.asarray(refs, dtype=float))
            if np.all(np.isfinite(y)) and np.all(np.isfinite(r)):
                if self._restart:  # the first step after a switch in Automatic
                    z = self._bumpless(y, self._u_prev - mdl.u_e, r)
                    self.kf.reset(z[: mdl.n], z[mdl.n:])
                    self._restart = False
                x, d = self.kf.correct(y)
                xs, us = self.design.prediction.target(d, r)
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
