"""Many closed-loop experiments at once, vectorized over the batch (numpy).

The engine runs one experiment a sample at a time, as the rig does.  Studies need
hundreds (seeds of a PRBS, a grid of tunings): this runs N experiments of the same
plant with decentralized PI control in lock-step, each numpy operation acting on all
N at once.  The loop is the engine's, term by term: y = kc h / 10; v = K (b r - y) + I;
u = sat(v); I += K h / Ti (r - y) + h / Tr (u - v) (PIDParams' algorithm without the D
part); the levels advance over the sample with u held.  The plant is integrated with
classical RK4 on fixed sub-steps (default 0.25 s, far below the fastest time
constant, ~20 s), with the same flow law as core.plant.rhs (the film blend near
empty, the spill at the brim); it agrees with the engine's adaptive integrator to
about 1e-9 normalized over an hour.

Example
-------
>>> import numpy as np
>>> from quadtank_tui.core.pid import PIDParams
>>> from quadtank_tui.core.plant import P_MINUS, steady_state_levels
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

from quadtank_tui.core.matrix import U_MAX, U_MIN
from quadtank_tui.core.pid import PIDParams
from quadtank_tui.core.plant import FULL_SCALE_V, H_FILM, PlantParams

#: Default RK4 sub-step, s: the local error (s / T)^5 / 120 is ~1e-12 for the
#: fastest tank (T ~ 20 s).
SUBSTEP = 0.25


@dataclass(frozen=True)
class BatchRun:
    """y : (N, K, 4) levels read at each sample; u : (N, K, 2) applied inputs;
    both normalized, sample k at time k h."""

    y: np.ndarray
    u: np.ndarray


def _outflow(x: np.ndarray, a: np.ndarray, g: float) -> np.ndarray:
    """core.plant.outflow for arrays; rows of `x` are tanks, `a` their outlets (4, 1)."""
    q = a * np.sqrt(2.0 * g * np.maximum(x, 0.0))
    low = x < H_FILM
    if low.any():  # the film blend near empty (rare: only where a tank runs dry)
        film = a * math.sqrt(2.0 * g) * (x / math.sqrt(H_FILM)) * (1.5 - 0.5 * x / H_FILM)
        q = np.where(low, np.where(x <= 0.0, 0.0, film), q)
    return q


def rhs_batch(x: np.ndarray, v: np.ndarray, p: PlantParams) -> np.ndarray:
    """dh/dt (cm/s) of N plants: x (4, N) cm, v (2, N) V (core.plant.rhs, vectorized)."""
    q = _outflow(x, np.array([[p.a1], [p.a2], [p.a3], [p.a4]]), p.g)
    v1 = np.maximum(v[0], 0.0)
    v2 = np.maximum(v[1], 0.0)
    f = np.stack((
        (-q[0] + q[2] + p.gamma1 * p.k1 * v1) / p.A1,
        (-q[1] + q[3] + p.gamma2 * p.k2 * v2) / p.A2,
        (-q[2] + (1.0 - p.gamma2) * p.k2 * v2) / p.A3,
        (-q[3] + (1.0 - p.gamma1) * p.k1 * v1) / p.A4,
    ))
    full = x >= p.hmax
    if full.any():  # a full tank spills what would raise it
        f = np.where(full & (f > 0.0), 0.0, f)
    return f


def advance_batch(x: np.ndarray, v: np.ndarray, dt: float, p: PlantParams, *, substep: float = SUBSTEP) -> np.ndarray:
    """Levels (4, N) cm after dt s with voltages v (2, N) held: RK4, clipped to [0, hmax]."""
    n = max(1, math.ceil(dt / substep - 1e-9))
    s = dt / n
    for _ in range(n):
        k1 = rhs_batch(x, v, p)
        k2 = rhs_batch(x + 0.5 * s * k1, v, p)
        k3 = rhs_batch(x + 0.5 * s * k2, v, p)
        k4 = rhs_batch(x + s * k3, v, p)
        x = np.clip(x + s / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4), 0.0, p.hmax)
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
        x = advance_batch(x, FULL_SCALE_V * u, h, p, substep=substep)
    ys, us = ys.transpose(2, 0, 1), us.transpose(2, 0, 1)
    return BatchRun(np.ascontiguousarray(ys), np.ascontiguousarray(us))
