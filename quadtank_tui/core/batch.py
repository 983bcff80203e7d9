"""Many closed-loop experiments at once, vectorized over the batch (numpy).

The engine runs one experiment a sample at a time, as the rig does.  Studies need
hundreds (seeds of a PRBS, a grid of tunings): this runs N experiments of the same
plant with decentralized PI control in lock-step, each numpy operation acting on all
N at once.  The loop is the engine's, term by term: y = kc h / 10; v = K (b r - y) + I;
u = sat(v); I += K h / Ti (r - y) + h / Tr (u - v) (PIDParams' algorithm without the D
part); the levels advance over the sample with u held.  The plant is integrated with
classical RK4 on fixed sub-steps (default 0.25 s, far below the fastest time
constant, ~20 s), with the same flow law as johansson.rhs (the film blend near
empty, the spill at the brim); it agrees with the engine's adaptive integrator to
about 1e-9 normalized over an hour.

Example
-------
>>> import numpy as np
>>> from quadtank_tui.core.controllers.pid import PIDParams
>>> from quadtank_tui.core.plants.johansson import P_MINUS, steady_state_levels
>>> h0 = steady_state_levels((3.0, 3.0), P_MINUS.params)
>>> y0 = [P_MINUS.params.kc * x / 10 for x in h0[:2]]
>>> refs = np.tile(np.array(y0) + [0.05, 0.0], (2, 100, 1))     # 2 experiments, 100 samples
>>> run = pi_batch(P_MINUS.params, h0, (0.3, 0.3), refs, (PIDParams(3.0, 30.0), PIDParams(2.7, 40.0)), 1.0)
>>> run.y.shape, run.u.shape
((2, 100, 4), (2, 100, 2))
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from quadtank_tui.core.controllers.matrix import U_MAX, U_MIN
from quadtank_tui.core.controllers.pid import PIDParams
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.plants.johansson import H_FILM, PlantParams

#: Default RK4 sub-step, s: the local error (s / T)^5 / 120 is ~1e-12 for the
#: fastest tank (T ~ 20 s).
SUBSTEP = 0.25


@dataclass(frozen=True)
class BatchRun:
    """y : (N, K, 4) levels read at each sample; u : (N, K, 2) applied inputs;
    both normalized, sample k at time k h."""

    y: np.ndarray
    u: np.ndarray


def _root_level(x: np.ndarray) -> np.ndarray:
    """johansson.outflow / (a sqrt(2 g)) for arrays of levels (cm): sqrt(h), with the
    film blend near empty; the outlet's area and gravity are in the flow matrix."""
    r = np.sqrt(np.maximum(x, 0.0))
    low = x < H_FILM
    if low.any():  # the film blend near empty (rare: only where a tank runs dry)
        film = (x / math.sqrt(H_FILM)) * (1.5 - 0.5 * x / H_FILM)
        r = np.where(low, np.where(x <= 0.0, 0.0, film), r)
    return r


@dataclass(frozen=True)
class _Flows:
    """dh/dt = F sqrt(h) + G v+ (cm/s), the plant's balance as two small matrices:
    F (4, 4) takes each outlet's flow a sqrt(2 g h) out of its tank and into the one
    below; G (4, 2) splits each pump's k v between its two tanks by the valve.  Four
    numpy operations a right-hand side instead of thirty (johansson.rhs's terms)."""

    F: np.ndarray
    G: np.ndarray
    hmax: float

    @classmethod
    def of(cls, p: PlantParams) -> _Flows:
        area = np.array([p.A1, p.A2, p.A3, p.A4])
        out = np.array([p.a1, p.a2, p.a3, p.a4]) * math.sqrt(2.0 * p.g)
        F = -np.diag(out)
        F[0, 2], F[1, 3] = out[2], out[3]  # tank 3 drains into 1, tank 4 into 2
        G = np.array([[p.gamma1 * p.k1, 0.0], [0.0, p.gamma2 * p.k2],
                      [0.0, (1.0 - p.gamma2) * p.k2], [(1.0 - p.gamma1) * p.k1, 0.0]])
        return cls(F / area[:, None], G / area[:, None], p.hmax)

    def rhs(self, x: np.ndarray, inflow: np.ndarray) -> np.ndarray:
        """dh/dt (cm/s) at levels x (4, N) with the pumps' share `inflow` (4, N) = G v+."""
        f = self.F @ _root_level(x)
        f += inflow
        full = x >= self.hmax
        if full.any():  # a full tank spills what would raise it
            f = np.where(full & (f > 0.0), 0.0, f)
        return f


def rhs_batch(x: np.ndarray, v: np.ndarray, p: PlantParams) -> np.ndarray:
    """dh/dt (cm/s) of N plants: x (4, N) cm, v (2, N) V (johansson.rhs, vectorized)."""
    flows = _Flows.of(p)
    return flows.rhs(x, flows.G @ np.maximum(v, 0.0))


def advance_batch(x: np.ndarray, v: np.ndarray, dt: float, p: PlantParams, *, substep: float = SUBSTEP) -> np.ndarray:
    """Levels (4, N) cm after dt s with voltages v (2, N) held: RK4, clipped to [0, hmax]."""
    return _advance(x, v, dt, _Flows.of(p), substep)


def _advance(x: np.ndarray, v: np.ndarray, dt: float, flows: _Flows, substep: float) -> np.ndarray:
    """advance_batch with the plant's matrices built once (pi_batch's every sample)."""
    inflow = flows.G @ np.maximum(v, 0.0)  # held over the sample
    n = max(1, math.ceil(dt / substep - 1e-9))
    s = dt / n
    for _ in range(n):
        k1 = flows.rhs(x, inflow)
        k2 = flows.rhs(x + 0.5 * s * k1, inflow)
        k3 = flows.rhs(x + 0.5 * s * k2, inflow)
        k4 = flows.rhs(x + s * k3, inflow)
        k2 += k3
        k2 *= 2.0
        k2 += k1
        k2 += k4
        k2 *= s / 6.0
        k2 += x
        x = np.clip(k2, 0.0, flows.hmax, out=k2)
    return x


def pi_batch(
    p: PlantParams,
    h0: Sequence[float],
    u0: Sequence[float],
    refs: np.ndarray,
    pi: tuple[PIDParams, PIDParams],
    h: float,
    *,
    substep: float = SUBSTEP,
) -> BatchRun:
    """N experiments of K samples: decentralized PI, references `refs` (N, K, 2).

    Each starts at levels `h0` (cm) with the controllers having tracked the inputs
    `u0` in Manual (PID.track at r = y), so a reference equal to y0 starts at rest.
    The D parts of `pi` must be off (PIDParams.derivative False or Td = 0).
    """
    refs = np.asarray(refs, dtype=float)
    if refs.ndim != 3 or refs.shape[2] != 2:
        raise ValueError(f"refs must be (N, K, 2), got {refs.shape}")
    if any(c.derivative and c.Td > 0.0 for c in pi):
        raise ValueError("the batch path runs PI controllers: switch the D parts off")
    n, k_total, _ = refs.shape
    K = np.array([[pi[0].K], [pi[1].K]])
    b = np.array([[pi[0].b], [pi[1].b]])
    gain_i = np.array([[c.K * h / c.Ti if c.integral else 0.0] for c in pi])
    track = np.array([[h / c.Tr if c.integral else 0.0] for c in pi])
    x = np.tile(np.asarray(h0, dtype=float)[:, None], (1, n))      # (4, N): rows are tanks
    y0 = p.kc * x[:2] / FULL_SCALE_V
    integ = np.asarray(u0, dtype=float)[:, None] - K * (b * y0 - y0)   # PID.track at r = y0
    rt = np.ascontiguousarray(refs.transpose(1, 2, 0))               # (K, 2, N)
    flows = _Flows.of(p)
    ys = np.empty((k_total, 4, n))
    us = np.empty((k_total, 2, n))
    for k in range(k_total):
        y = p.kc * x / FULL_SCALE_V
        r = rt[k]
        e = r - y[:2]
        v = K * (b * r - y[:2]) + integ
        u = np.clip(v, U_MIN, U_MAX)
        integ = integ + gain_i * e + track * (u - v)
        ys[k], us[k] = y, u
        x = _advance(x, FULL_SCALE_V * u, h, flows, substep)
    ys, us = ys.transpose(2, 0, 1), us.transpose(2, 0, 1)
    return BatchRun(np.ascontiguousarray(ys), np.ascontiguousarray(us))
