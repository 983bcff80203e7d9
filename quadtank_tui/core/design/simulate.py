"""Closed-loop step responses of a PI/PID loop around a DelayTF, delay exact.

The time step h divides the dead time exactly (L = m h), so the delayed process
input is a buffer of past controller outputs, never an approximation of e^-sL.
Process and controller (integrator and derivative filter) form one continuous
linear system driven by the delayed input; it is discretized exactly (matrix
exponential) and the delayed input held over a step at the mean of its two
end values, which makes the scheme second-order accurate in h (the tests check
that halving h moves IAE by < 0.1 %).

Signals: r the setpoint, d a load step added at the process input (Andersson's
V), u the controller output, y the process output, e = r - y.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import tf2ss

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.pid_tuning import PIDTuning
from quadtank_tui.core.plants.linear import zoh

#: steps per 1/wc (closed-loop time scale) at least; see module docstring.
STEPS_PER_RAD = 20.0
MAX_STEPS = 400_000


@dataclass(frozen=True)
class Response:
    """Sampled closed-loop response (t in s)."""

    t: np.ndarray
    y: np.ndarray
    u: np.ndarray
    r: float
    d: float

    @property
    def e(self) -> np.ndarray:
        return self.r - self.y


def _augmented(g: DelayTF, c: PIDTuning) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float,
                                             np.ndarray, np.ndarray, float, np.ndarray]:
    """Continuous z' = A z + Bv v + Bw [r, d]; y = Cy z + Dy v; u = F z + Fv v + Fw [r, d].

    z = [process states, integral of e, derivative-filter state]; v is the
    (delayed) controller output reaching the process, to which d is added.
    """
    Ap, Bp, Cp, Dp = tf2ss(np.array(g.num), np.array(g.den))
    n = Ap.shape[0]
    has_i = math.isfinite(c.Ti)
    has_d = c.Td > 0.0
    nz = n + 2
    A = np.zeros((nz, nz))
    Bv = np.zeros(nz)
    Bw = np.zeros((nz, 2))
    Cy = np.zeros(nz)
    A[:n, :n] = Ap
    Bv[:n] = Bp[:, 0]
    Bw[:n, 1] = Bp[:, 0]
    Cy[:n] = Cp[0]
    dy = float(Dp[0, 0]) if Dp.size else 0.0
    Dyw = np.array([0.0, dy])  # d also passes D
    # integrator: xi' = r - y
    if has_i:
        A[n, :] -= Cy
        Bv[n] -= dy
        Bw[n] += np.array([1.0, 0.0]) - Dyw
    # filter: xf' = (N/Td)(y - xf); derivative term -Kc N (y - xf)
    if has_d:
        a = c.N / c.Td
        A[n + 1, :] += a * Cy
        A[n + 1, n + 1] -= a
        Bv[n + 1] += a * dy
        Bw[n + 1] += a * Dyw
    # u = Kc (b r - y) + Kc/Ti xi - Kc N (y - xf)
    ky = c.Kc * (1.0 + (c.N if has_d else 0.0))
    F = -ky * Cy
    if has_i:
        F[n] += c.Kc / c.Ti
    if has_d:
        F[n + 1] += c.Kc * c.N
    Fv = -ky * dy
    Fw = np.array([c.Kc * c.b, 0.0]) - ky * Dyw
    return A, Bv, Bw, Cy, dy, Dyw, F, Fv, Fw


def step_response(g: DelayTF, c: PIDTuning, *, r: float = 0.0, d: float = 0.0,
                  horizon: float, h: float) -> Response:
    """Response from rest to a setpoint step r and a load step d at t = 0."""
    A, Bv, Bw, Cy, dy, Dyw, F, Fv, Fw = _augmented(g, c)
    w = np.array([r, d])
    m = int(round(g.delay / h)) if g.delay > 0.0 else 0
    if m > 0:
        h = g.delay / m
    steps = int(math.ceil(horizon / h))
    if steps > MAX_STEPS:
        raise ValueError(f"a simulation of {steps} steps is too long (h = {h:g} s)")
    nz = A.shape[0]
    if m == 0:  # no delay: close the loop algebraically, v = u
        if abs(1.0 - Fv) < 1e-12:
            raise ValueError("algebraic loop: the loop gain at infinite frequency is -1")
        Acl = A + np.outer(Bv, F) / (1.0 - Fv)
        Bcl = Bw + np.outer(Bv, Fw) / (1.0 - Fv)
        Ad, Bd = zoh(Acl, Bcl, h)
        bd = Bd @ w
        z = np.zeros(nz)
        y = np.empty(steps + 1)
        u = np.empty(steps + 1)
        for k in range(steps + 1):
            uk = float(F @ z + Fw @ w) / (1.0 - Fv)
            y[k] = Cy @ z + dy * uk + Dyw @ w
            u[k] = uk
            z = Ad @ z + bd
        return Response(np.arange(steps + 1) * h, y, u, r, d)
    # the load passes the delay with u (Y = G (U + V), G with its dead time): it is a
    # step reaching the process at t = L = m h, held exactly from that sample on
    Ad, Bd = zoh(A, np.column_stack([Bv, Bw]), h)
    bv, br, bd = Bd[:, 0], Bd[:, 1] * r, Bd[:, 2] * d
    fw = float(Fw[0] * r)
    ring = [0.0] * (m + 1)  # u_i in slot i % (m+1); from rest, earlier u are 0
    z = np.zeros(nz)
    # one product a step gives A_d z, y and u (both linear in z); the constant
    # inputs (r, and d once it has passed the delay) are folded into one vector
    big = np.vstack([Ad, Cy, F])
    const = (br, br + bd)
    half_bv = 0.5 * bv
    y = np.empty(steps + 1)
    u = np.empty(steps + 1)
    size = m + 1
    for k in range(steps + 1):
        v_now = ring[(k + 1) % size]  # u(t_k - L)
        arrived = k >= m
        v_in = v_now + d if arrived else v_now
        prod = big @ z
        y[k] = prod[nz] + dy * v_in
        uk = prod[nz + 1] + Fv * v_in + fw
        u[k] = uk
        ring[k % size] = uk
        # u(t - L) over the step: the mean of its end values (second order in h)
        z = prod[:nz] + half_bv * (v_now + ring[(k + 2) % size]) + const[arrived]
    return Response(np.arange(steps + 1) * h, y, u, r, d)
