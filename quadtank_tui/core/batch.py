"""Many closed-loop experiments at once, vectorized over the batch (numpy).

The engine runs one experiment a sample at a time, as the rig does.  Studies need
hundreds (seeds of a PRBS, a grid of tunings): this runs N experiments of the same
plant (or of N plants, a spread of its constants) with decentralized PID control in lock-step, each numpy operation acting on all
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
    """dh/dt = -out sqrt(h) + down sqrt(h3, h4) + G v+ (cm/s), the plant's balance as
    arrays broadcast over the batch (one plant: a column; N plants: N columns): out
    (4, n) each outlet's a sqrt(2 g) / A, down (2, n) tank 3's outflow into 1 and 4's
    into 2 (per area of the tank below), G (4, 2, n) each pump's k split by its valve."""

    out: np.ndarray
    down: np.ndarray
    G: np.ndarray
    hmax: np.ndarray
    hmax_min: float

    @classmethod
    def of(cls, p: PlantParams | Sequence[PlantParams]) -> _Flows:
        ps = [p] if isinstance(p, PlantParams) else list(p)
        area = np.array([[q.A1, q.A2, q.A3, q.A4] for q in ps]).T
        out = np.array([[q.a1, q.a2, q.a3, q.a4] for q in ps]).T * np.sqrt(2.0 * np.array([q.g for q in ps]))
        down = out[2:] / area[:2]
        G = np.zeros((4, 2, len(ps)))
        for n, q in enumerate(ps):
            G[:, :, n] = [[q.gamma1 * q.k1, 0.0], [0.0, q.gamma2 * q.k2],
                          [0.0, (1.0 - q.gamma2) * q.k2], [(1.0 - q.gamma1) * q.k1, 0.0]]
        hmax = np.array([[q.hmax for q in ps]])
        return cls(out / area, down, G / area[:, None, :], hmax, float(hmax.min()))

    def inflow(self, v: np.ndarray) -> np.ndarray:
        """G v+ (4, N) of the pump voltages v (2, N)."""
        vp = np.maximum(v, 0.0)
        return self.G[:, 0, :] * vp[0] + self.G[:, 1, :] * vp[1]

    def rhs(self, x: np.ndarray, inflow: np.ndarray) -> np.ndarray:
        """dh/dt (cm/s) at levels x (4, N) with the pumps' share `inflow` (4, N) = G v+:
        the film blend only when some level is near empty, the spill only when some
        tank is at its brim (each a minimum or a maximum to find out)."""
        r = _root_level(x) if x.min() < H_FILM else np.sqrt(x)
        f = inflow - self.out * r
        f[:2] += self.down * r[2:]
        if x.max() >= self.hmax_min:  # a full tank spills what would raise it
            f = np.where((x >= self.hmax) & (f > 0.0), 0.0, f)
        return f


def rhs_batch(x: np.ndarray, v: np.ndarray, p: PlantParams) -> np.ndarray:
    """dh/dt (cm/s) of N plants: x (4, N) cm, v (2, N) V (johansson.rhs, vectorized)."""
    flows = _Flows.of(p)
    return flows.rhs(x, flows.inflow(v))


def advance_batch(x: np.ndarray, v: np.ndarray, dt: float, p: PlantParams, *, substep: float = SUBSTEP) -> np.ndarray:
    """Levels (4, N) cm after dt s with voltages v (2, N) held: RK4, clipped to [0, hmax]."""
    return _advance(x, v, dt, _Flows.of(p), substep)


def _advance(x: np.ndarray, v: np.ndarray, dt: float, flows: _Flows, substep: float) -> np.ndarray:
    """advance_batch with the plant's matrices built once (pi_batch's every sample)."""
    inflow = flows.inflow(v)  # held over the sample
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
        x = np.minimum(np.maximum(k2, 0.0, out=k2), flows.hmax, out=k2)
    return x


def pi_batch(
    p: PlantParams | Sequence[PlantParams],
    h0: Sequence[float] | np.ndarray,
    u0: Sequence[float] | np.ndarray,
    refs: np.ndarray,
    pi: tuple[PIDParams, PIDParams],
    h: float,
    *,
    substep: float = SUBSTEP,
) -> BatchRun:
    """N experiments of K samples: decentralized PID, references `refs` (N, K, 2).

    `p`: one plant for all, or N plants (a spread of constants); `h0` (4,) or
    (N, 4) starting levels (cm), `u0` (2,) or (N, 2) inputs the controllers tracked
    in Manual (PID.track at r = y), so a reference equal to y0 starts at rest.  The
    D part, where on, is core.pid's (on a r - y, filtered by N, no kick at the start).
    """
    refs = np.asarray(refs, dtype=float)
    if refs.ndim != 3 or refs.shape[2] != 2:
        raise ValueError(f"refs must be (N, K, 2), got {refs.shape}")
    n, k_total, _ = refs.shape
    ps = [p] * n if isinstance(p, PlantParams) else list(p)
    if len(ps) != n:
        raise ValueError(f"{len(ps)} plants for {n} experiments")
    K = np.array([[pi[0].K], [pi[1].K]])
    b = np.array([[pi[0].b], [pi[1].b]])
    a = np.array([[c.a] for c in pi])
    gain_i = np.array([[c.K * h / c.Ti if c.integral else 0.0] for c in pi])
    track = np.array([[h / c.Tr if c.integral else 0.0] for c in pi])
    d_on = [c.derivative and c.Td != 0.0 for c in pi]
    ad = np.array([[c.Td / (c.Td + c.N * h) if on else 0.0] for c, on in zip(pi, d_on)])
    bd = np.array([[c.K * c.Td * c.N / (c.Td + c.N * h) if on else 0.0] for c, on in zip(pi, d_on)])
    x = np.array(np.broadcast_to(np.asarray(h0, dtype=float).T.reshape(4, -1), (4, n)))  # (4, N): rows are tanks
    kc = np.array([[q.kc for q in ps]])
    y0 = kc * x[:2] / FULL_SCALE_V
    u_start = np.broadcast_to(np.asarray(u0, dtype=float).T.reshape(2, -1), (2, n))
    integ = u_start - K * (b * y0 - y0)   # PID.track at r = y0
    D = np.zeros((2, n))
    last: np.ndarray | None = None
    rt = np.ascontiguousarray(refs.transpose(1, 2, 0))               # (K, 2, N)
    flows = _Flows.of(ps)
    ys = np.empty((k_total, 4, n))
    us = np.empty((k_total, 2, n))
    any_d = any(d_on)
    for k in range(k_total):
        y = kc * x / FULL_SCALE_V
        r = rt[k]
        e = r - y[:2]
        if any_d:
            now = a * r - y[:2]
            D = ad * D + (bd * (now - last) if last is not None else 0.0)
            last = now
        v = K * (b * r - y[:2]) + integ + D
        u = np.clip(v, U_MIN, U_MAX)
        integ = integ + gain_i * e + track * (u - v)
        ys[k], us[k] = y, u
        x = _advance(x, FULL_SCALE_V * u, h, flows, substep)
    ys, us = ys.transpose(2, 0, 1), us.transpose(2, 0, 1)
    return BatchRun(np.ascontiguousarray(ys), np.ascontiguousarray(us))
