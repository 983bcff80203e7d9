"""The loop as it runs: a model behind a zero-order hold, sampled every h seconds,
closed by the PID of core.controllers.pid (its own discretization), pumps limited to 0..1.

Exact at the sampling instants, no approximation of the hold or of the dead time:

* the process K(s) e^(-sL) behind a ZOH (Astrom & Wittenmark, 2.3: a delay of
  d whole samples and a fraction tau = L - d h),
  x(k+1) = Phi x(k) + Gamma0 u(k-d) + Gamma1 u(k-d-1),
  Gamma0 = int_0^(h-tau) e^(As) ds B,  Gamma1 = e^(A(h-tau)) int_0^tau e^(As) ds B;
* the controller as core.controllers.pid computes it (forward-difference integral, backward-
  difference filtered derivative on y): from -y to u,
  C(z) = K [1 + h/(Ti (z-1)) + Td N/(Td + N h) (1 - 1/z)/(1 - ad/z)], ad = Td/(Td + N h).

The frequency figures (Ms, margins, crossover) are those of L(e^(iwh)) = C(z) G(z)
for 0 < w < pi/h; stability is the closed loop's eigenvalues (|z| < 1); the time
figures are simulations with core.controllers.pid's own PID object (anti-windup included).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import tf2ss

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.pid_tuning import PIDTuning, DesignError
from quadtank_tui.core.plants.linear import zoh

GRID_POINTS = 3000
#: the sampled model keeps one state per sample of dead time: beyond this, refused
MAX_DELAY_SAMPLES = 1000


@dataclass(frozen=True)
class SampledModel:
    """K(s) e^(-sL) behind a ZOH at h, as x(k+1) = A x(k) + B u(k), y(k) = C x(k)
    (+ Dd u(k)): the state holds the process's states and the last d+1 inputs."""

    h: float
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Dd: float
    # the parts, for the frequency response
    Phi: np.ndarray
    Gamma0: np.ndarray
    Gamma1: np.ndarray
    Cp: np.ndarray
    Dp: float
    d: int
    tau: float

    def freqresp(self, w: np.ndarray) -> np.ndarray:
        """G(e^(iwh)) at each w (rad/s)."""
        w = np.asarray(w, dtype=float)
        z = np.exp(1j * w * self.h)
        n = self.Phi.shape[0]
        direct = self.Dp / z if self.tau > 0.0 else np.full(z.shape, self.Dp, dtype=complex)
        if n:  # one batched solve: (z I - Phi) x = Gamma0 + Gamma1/z at every z
            M = z[:, None, None] * np.eye(n)[None] - self.Phi[None]
            rhs = self.Gamma0[None, :] + self.Gamma1[None, :] / z[:, None]
            x = np.linalg.solve(M, rhs[..., None])[..., 0]
            direct = direct + x @ self.Cp
        return direct * z ** (-self.d)


def sample(g: DelayTF, h: float) -> SampledModel:
    """The exact ZOH model of g (dead time included) at sampling time h > 0 (kept:
    a table designs and evaluates nine candidates on the same model)."""
    return _sample(g.num, g.den, g.delay, float(h))


@functools.lru_cache(maxsize=64)
def _sample(num: tuple[float, ...], den: tuple[float, ...], delay: float, h: float) -> SampledModel:
    g = DelayTF(num, den, delay)
    if not (h > 0.0 and math.isfinite(h)):
        raise DesignError(f"the sampling time must be > 0 s, got {h:g}")
    A, B, C, D = tf2ss(np.array(g.num, dtype=float), np.array(g.den, dtype=float))
    n = A.shape[0]
    A, B, C = A.reshape(n, n), B.reshape(n, 1), C.reshape(1, n)
    dp = float(D.ravel()[0]) if D.size else 0.0
    d = int(math.floor(g.delay / h + 1e-9))
    if d > MAX_DELAY_SAMPLES:
        raise DesignError(f"the dead time {g.delay:g} s is {d} samples of {h:g} s: more than "
                          f"{MAX_DELAY_SAMPLES}; sample slower")
    tau = max(0.0, g.delay - d * h)
    if tau < 1e-9 * h:
        tau = 0.0
    Phi, _ = zoh(A, B, h) if n else (np.zeros((0, 0)), np.zeros((0, 1)))
    if n:
        phi_rest, g_rest = zoh(A, B, h - tau)
        _, g_tau = zoh(A, B, tau) if tau > 0.0 else (None, np.zeros((n, 1)))
        gamma0, gamma1 = g_rest[:, 0], (phi_rest @ g_tau)[:, 0]
    else:
        gamma0 = gamma1 = np.zeros(0)
    # state: [x (n), u(k-1) ... u(k-d-1)]; u(k-j) is u(k) for j = 0, else buffer slot j
    m = d + 1
    N = n + m
    Aa, Ba, Ca = np.zeros((N, N)), np.zeros(N), np.zeros(N)
    Aa[:n, :n] = Phi

    def feed(j: int, vec: np.ndarray) -> None:  # x(k+1) += vec u(k-j)
        if j == 0:
            Ba[:n] += vec
        else:
            Aa[:n, n + j - 1] += vec

    feed(d, gamma0)
    feed(d + 1, gamma1)
    Ba[n] = 1.0  # u(k-1)' = u(k)
    for j in range(1, m):
        Aa[n + j, n + j - 1] = 1.0
    Ca[:n] = C[0]
    lag = d + (1 if tau > 0.0 else 0)
    dd = 0.0
    if dp != 0.0:
        if lag == 0:
            dd = dp
        else:
            Ca[n + lag - 1] += dp
    return SampledModel(h, Aa, Ba, Ca, dd, Phi, gamma0, gamma1, C[0], dp, d, tau)


def derivative_gain(c: PIDTuning, h: float) -> tuple[float, float]:
    """(ad, Td N/(Td + N h)): core.controllers.pid's backward-difference filter at h."""
    if c.Td <= 0.0:
        return 0.0, 0.0
    den = c.Td + c.N * h
    return c.Td / den, c.Td * c.N / den


def derivative_shape(td: float, n: float, h: float, w: np.ndarray) -> np.ndarray:
    """1 + the derivative part of C(z)/K at e^(iwh) (the D of the Ms search)."""
    zi = np.exp(-1j * np.asarray(w) * h)
    if td <= 0.0:
        return np.ones_like(zi)
    den = td + n * h
    ad, gd = td / den, td * n / den
    return 1.0 + gd * (1.0 - zi) / (1.0 - ad * zi)


def integral_shape(h: float, w: np.ndarray) -> np.ndarray:
    """h/(z - 1) at z = e^(iwh): the forward-difference integral (1/(iw) as h -> 0)."""
    return h / (np.exp(1j * np.asarray(w) * h) - 1.0)


def controller_freqresp(c: PIDTuning, h: float, w: np.ndarray) -> np.ndarray:
    """C(e^(iwh)) from -y to u, as core.controllers.pid implements the PID."""
    integral = c.Kc / c.Ti * integral_shape(h, w) if math.isfinite(c.Ti) else 0.0
    return c.Kc * derivative_shape(c.Td, c.N, h, w) + integral


def controller_ss(c: PIDTuning, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(Ac, Bc, Cc, Dc): xc(k+1) = Ac xc + Bc y, u = Cc xc + Dc y (r = 0), states
    [I, D, y(k-1)] as core.controllers.pid keeps them (D and y(k-1) only with a derivative)."""
    ki = c.Kc * h / c.Ti if math.isfinite(c.Ti) else 0.0
    ad, gd = derivative_gain(c, h)
    bd = c.Kc * gd
    if c.Td <= 0.0:
        return np.array([[1.0]]), np.array([-ki]), np.array([1.0]), -c.Kc
    Ac = np.array([[1.0, 0.0, 0.0], [0.0, ad, bd], [0.0, 0.0, 0.0]])
    return Ac, np.array([-ki, -bd, 1.0]), np.array([1.0, ad, bd]), -(c.Kc + bd)


def closed_loop_matrix(models: list[list[SampledModel]], ctrls: list[PIDTuning], h: float) -> np.ndarray:
    """The state matrix of the decentralized loop u_i = C_i(-y_i) around a matrix of
    sampled elements (y_i = sum_j G_ij u_j); 1x1 for a single loop."""
    return closed_loop(models, ctrls, h)[0]


def closed_loop(models: list[list[SampledModel]], ctrls: list[PIDTuning], h: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(A, Bu, Bc, Y, U): z(k+1) = A z + Bu w_u + Bc w_c, y = Y z, u = U z + w_u for
    the states z = [elements, controllers] with w_u the controllers' direct
    setpoint terms (K b r) and w_c their integrators' (K h/Ti r), one per loop."""
    p = len(ctrls)
    blocks = [(i, j, models[i][j]) for i in range(p) for j in range(p)]
    ng = sum(b[2].A.shape[0] for b in blocks)
    css = [controller_ss(c, h) for c in ctrls]
    nc = sum(cs[0].shape[0] for cs in css)
    Ag, Bg, Cg, Dg = np.zeros((ng, ng)), np.zeros((ng, p)), np.zeros((p, ng)), np.zeros((p, p))
    k = 0
    for i, j, m in blocks:
        nb = m.A.shape[0]
        Ag[k:k + nb, k:k + nb], Bg[k:k + nb, j], Cg[i, k:k + nb] = m.A, m.B, m.C
        Dg[i, j] = m.Dd
        k += nb
    Ac, Bc, Cc, Dc = np.zeros((nc, nc)), np.zeros((nc, p)), np.zeros((p, nc)), np.zeros((p, p))
    k = 0
    for i, (a, b, cc, dc) in enumerate(css):
        nb = a.shape[0]
        Ac[k:k + nb, k:k + nb], Bc[k:k + nb, i], Cc[i, k:k + nb], Dc[i, i] = a, b, cc, dc
        k += nb
    if np.any(Dg != 0.0):
        # y = Cg xg + Dg u, u = Cc xc + Dc y: solve the algebraic loop once
        M = np.eye(p) - Dc @ Dg
        if abs(np.linalg.det(M)) < 1e-12:
            raise DesignError("algebraic loop: the sampled loop has no delay and a direct term")
        Mi = np.linalg.inv(M)
        Ku_x, Ku_c = Mi @ Dc @ Cg, Mi @ Cc  # u = Ku_x xg + Ku_c xc
    else:
        Ku_x, Ku_c = Dc @ Cg, Cc
    Y_x, Y_c = Cg + Dg @ Ku_x, Dg @ Ku_c  # y in the states
    top = np.hstack([Ag + Bg @ Ku_x, Bg @ Ku_c])
    bottom = np.hstack([Bc @ Y_x, Ac + Bc @ Y_c])
    # the integrator is each controller's first state (controller_ss)
    Bi = np.zeros((nc, p))
    k = 0
    for i, cs in enumerate(css):
        Bi[k, i] = 1.0
        k += cs[0].shape[0]
    Bu = np.vstack([Bg, np.zeros((nc, p))])
    return (np.vstack([top, bottom]), Bu, np.vstack([np.zeros((ng, p)), Bi]),
            np.hstack([Y_x, Y_c]), np.hstack([Ku_x, Ku_c]))


def closed_loop_poles(g: DelayTF | SampledModel, c: PIDTuning, h: float) -> np.ndarray:
    """z-plane poles of one sampled loop (stable: all |z| < 1)."""
    m = g if isinstance(g, SampledModel) else sample(g, h)
    return np.linalg.eigvals(closed_loop_matrix([[m]], [c], h))


def slowest_rate(poles: np.ndarray, h: float) -> float:
    """ln max|z| / h, 1/s: the continuous-time real part of the slowest pole (>= 0: unstable)."""
    r = float(np.max(np.abs(poles))) if poles.size else 0.0
    return -math.inf if r == 0.0 else math.log(r) / h


def sampled_grid(g: DelayTF, h: float, points: int = GRID_POINTS) -> np.ndarray:
    """A log grid from well below the model's slowest characteristic frequency up to
    (just below) the Nyquist frequency pi/h."""
    from quadtank_tui.core.design.frequency import characteristic_frequencies

    nyq = math.pi / h
    lo = min(float(characteristic_frequencies(g).min()) * 1e-3, nyq * 1e-4)
    return np.logspace(math.log10(lo), math.log10(nyq * 0.9999), points)
