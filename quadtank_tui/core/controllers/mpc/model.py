"""The prediction model: the plant in use, linearized at its operating point and
discretized by zero-order hold at the sampling time, with the disturbance model
that makes tracking offset-free.

Deviations from the operating point (x_e, u_e), in the plant's own units (levels
in cm or m, pumps in V)::

    x+ = A x + B u + Bd d        d+ = d        (d: constant, estimated)
    y  = Cm x + Cd d             (the measured levels)
    z  = Cz x + Czd d            (the tracked levels, a subset of y)

With as many disturbances as measured levels and the augmented pair detectable, the
estimator's innovation vanishes at steady state, so every measured level, and so
every tracked one, reaches its reference whatever constant error the model has
(Pannocchia & Rawlings 2003; Muske & Badgwell 2002).

The plant comes from the parameters through :func:`plant_in_use`, the one place
that names them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import TYPE_CHECKING, Sequence

import numpy as np

from quadtank_tui.core.controllers.mpc.settings import SECTION, MPCSettings
from quadtank_tui.core.plants.base import Plant
from quadtank_tui.core.plants.linear import zoh
from quadtank_tui.core.controllers.statefb.placement import OperatingModel
from quadtank_tui.core.controllers.statefb.plants import _CM_PER_UNIT as CM_PER_UNIT  # LevelMargin is in cm
from quadtank_tui.core.controllers.statefb.plants import operating_model
from quadtank_tui.core.ranges import ParameterError

if TYPE_CHECKING:
    from quadtank_tui.core.parameters import Parameters

def plant_in_use(params: Parameters) -> tuple[Plant, tuple[float, ...]]:
    """The plant the parameters run (whatever its kind) and its operating levels."""
    return params.process_plant(), params.process_levels()


@dataclass(frozen=True, eq=False)
class MPCModel:
    """The discrete model and the limits, in deviations (see the module docstring).

    T : sampling time, s; x_e, u_e : the operating point (plant units)
    tracked, measured : state indices; u_lo, u_hi : pump range (V)
    x_lo, x_hi : soft level limits (plant units); y_scale, u_scale : the ranges the
    weights are relative to; Ac, Bc : the continuous linearization A, B come from
    (so the model can be sampled again on the prediction grid, :meth:`resampled`)
    """

    T: float
    A: np.ndarray
    B: np.ndarray
    Bd: np.ndarray
    Cm: np.ndarray
    Cd: np.ndarray
    Cz: np.ndarray
    Czd: np.ndarray
    x_e: np.ndarray
    u_e: np.ndarray
    tracked: tuple[int, ...]
    measured: tuple[int, ...]
    u_lo: np.ndarray
    u_hi: np.ndarray
    x_lo: np.ndarray
    x_hi: np.ndarray
    y_scale: np.ndarray
    u_scale: np.ndarray
    disturbance: str
    Ac: np.ndarray
    Bc: np.ndarray
    note: str = ""

    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def m(self) -> int:
        return self.B.shape[1]

    @property
    def nd(self) -> int:
        return self.Bd.shape[1]

    def resampled(self, k: int) -> MPCModel:
        """The same model at k times the sampling time (the MPC's prediction step):
        ZOH again from the continuous linearization; an input disturbance enters as
        the input does, a level offset stays one.  Its steady states are this model's
        (ZOH keeps the DC gain), so the disturbance estimate and the targets carry over."""
        if k == 1:
            return self
        A, B = zoh(self.Ac, self.Bc, k * self.T)
        Bd = np.hstack([B, self.Bd[:, self.m:]]) if self.disturbance == "input" else self.Bd
        return replace(self, T=k * self.T, A=A, B=B, Bd=Bd)

    def target(self, d: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The steady state (x_s, u_s) where the tracked levels equal r (deviations)
        with the disturbance d acting; r may be one reference or one per row."""
        rr = np.atleast_2d(r)
        rhs = np.concatenate([np.tile(self.Bd @ d, (rr.shape[0], 1)), rr - self.Czd @ d], axis=1)
        sol = rhs @ self._target_inverse.T
        xs, us = sol[:, : self.n], sol[:, self.n:]
        return (xs, us) if np.ndim(r) > 1 else (xs[0], us[0])

    @cached_property
    def _target_inverse(self) -> np.ndarray:
        return np.linalg.inv(self._target_matrix())

    def _target_matrix(self) -> np.ndarray:
        n, m = self.n, self.m
        return np.block([[np.eye(n) - self.A, -self.B], [self.Cz, np.zeros((self.Cz.shape[0], m))]])


def nearest_operating_model(plant: Plant, levels: Sequence[float]) -> tuple[OperatingModel, str]:
    """The linearization state feedback designs on (core.controllers.statefb.plants) at the
    operating levels; when no pump setting holds them (the two-input rig's file
    levels need pump 2 to run backwards without Murray-Smith's clogged drain), at the
    steady state of the pumps within their range whose tracked levels come closest,
    with a note saying so (else "")."""
    try:
        return operating_model(plant, levels), ""
    except ParameterError as exc:
        first = exc
    from scipy.optimize import minimize

    idx = list(plant.controlled)
    want = np.array([levels[i] for i in idx], dtype=float)
    scale = np.array([plant.states[i].hi for i in idx])
    bounds = [(sig.lo, sig.hi) for sig in plant.inputs]

    def miss(u: np.ndarray) -> float:
        return float(np.sum(((np.array(plant.steady_state(u.tolist()))[idx] - want) / scale) ** 2))

    start = np.array([0.5 * (lo + hi) for lo, hi in bounds])
    u = minimize(miss, start, bounds=bounds, method="L-BFGS-B").x.tolist()
    x = np.array(plant.steady_state(u))
    lin = plant.linearize(x.tolist(), u)
    C = np.eye(len(plant.states))[idx]
    om = OperatingModel(lin.A, lin.B, C, x, np.array(plant.saturate(u)),
                        u_min=np.array([sig.lo for sig in plant.inputs]), u_max=np.array([sig.hi for sig in plant.inputs]))
    levels_text = ", ".join(f"{v:.4g}" for v in x)
    return om, f"{first.reason}; linearized at the nearest steady state instead, levels ({levels_text})"


def build_model(plant: Plant, levels: Sequence[float], s: MPCSettings, T: float) -> MPCModel:
    """The prediction model of `plant` at its operating `levels`, sampled at T s;
    ParameterError names the setting that makes it impossible."""
    om, note = nearest_operating_model(plant, levels)
    A, B = zoh(om.A, om.B, T)
    n, m = B.shape
    tracked = tuple(plant.controlled)
    measured = s.check_plant(plant.kind, n, tracked, m)
    p = len(measured)
    Cm = np.eye(n)[list(measured)]
    if s.disturbance == "input":
        # a level offset on each measured tank beyond the pump count, untracked ones first
        extra = ([i for i in measured if i not in tracked] + [i for i in measured if i in tracked])[: p - m]
        Bd = np.hstack([B, np.zeros((n, len(extra)))])
        Cd = np.hstack([np.zeros((p, m)), np.eye(p)[:, [measured.index(i) for i in extra]]])
    else:
        Bd = np.zeros((n, p))
        Cd = np.eye(p)
    rows = [measured.index(i) for i in tracked]
    Cz, Czd = Cm[rows], Cd[rows]
    nd = Bd.shape[1]
    obs = np.block([[np.eye(n) - A, -Bd], [Cm, Cd]])
    if np.linalg.matrix_rank(obs) < n + nd:
        raise ParameterError(f"{SECTION}.Disturbance",
                             f"the {s.disturbance} disturbances cannot be told apart from the measured levels")
    cm = np.array([CM_PER_UNIT.get(st.unit, 1.0) for st in plant.states])
    x_lo = np.array([st.lo for st in plant.states])
    x_hi = np.array([st.hi for st in plant.states]) - s.level_margin / cm
    if np.any(x_hi <= x_lo) or np.any(om.x_e >= x_hi):
        raise ParameterError(f"{SECTION}.LevelMargin",
                             f"{s.level_margin:g} cm puts a level limit below the operating point")
    model = MPCModel(
        T=float(T), A=A, B=B, Bd=Bd, Cm=Cm, Cd=Cd, Cz=Cz, Czd=Czd,
        x_e=np.array(om.x_e, dtype=float), u_e=np.array(om.u_e, dtype=float), tracked=tracked, measured=measured,
        u_lo=np.array(om.u_min, dtype=float), u_hi=np.array(om.u_max, dtype=float), x_lo=x_lo, x_hi=x_hi,
        y_scale=np.array([st.hi - st.lo for st in plant.states]),
        u_scale=np.array([sig.hi - sig.lo for sig in plant.inputs]), disturbance=s.disturbance,
        Ac=np.asarray(om.A, dtype=float), Bc=np.asarray(om.B, dtype=float), note=note)
    if np.linalg.cond(model._target_matrix()) > 1e12:
        raise ParameterError(f"{SECTION}.Measured", "the tracked levels have no unique steady state (a zero at s = 0)")
    return model
