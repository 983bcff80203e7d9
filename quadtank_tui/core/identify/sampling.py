"""Continuous models against sampled records: zero-order-hold discretization with an
exact (fractional) dead time, and its inverse for state-space models.

Sampling convention of our logs: row k holds y measured at t_k and the input u_k
applied from t_k to t_k+1, so y_k never sees u_k.  A model's response at the instant
of an input change is therefore its left limit (a direct term D acts one row later),
as in the step-response closed forms.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import linalg, signal

from quadtank_tui.core.identify import IdentificationError


def expm_small(M: np.ndarray) -> np.ndarray:
    """e^M for the few-state matrices here: scaling and squaring with an 18-term
    Taylor series (error below 1e-16 relative at ||M / 2^s|| <= 1/2).  scipy's expm
    costs about 4 ms per call on such a matrix, mostly overhead, and a fit calls it
    hundreds of times."""
    norm = float(np.abs(M).sum(axis=1).max())
    s = max(0, int(math.ceil(math.log2(norm / 0.5)))) if norm > 0.5 else 0
    X = M / 2.0**s
    E = np.eye(M.shape[0])
    term = np.eye(M.shape[0])
    for k in range(1, 19):
        term = term @ X / k
        E = E + term
    for _ in range(s):
        E = E @ E
    return E


def _zoh_integrals(A: np.ndarray, B: np.ndarray, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """e^(A tau) and the integral of e^(A s) ds B over [0, tau]."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    E = expm_small(M * tau)
    return E[:n, :n], E[:n, n:]


def zoh_filter(num: np.ndarray, den: np.ndarray, h: float, delay: float = 0.0
               ) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) in powers of z^-1 such that lfilter(b, a, u) is the sampled output of
    num(s)/den(s) e^(-delay s) driven by the piecewise-constant u (at rest before)."""
    num = np.atleast_1d(np.asarray(num, dtype=float))
    den = np.atleast_1d(np.asarray(den, dtype=float))
    if not (math.isfinite(delay) and delay >= 0):
        raise IdentificationError(f"the delay must be >= 0 s, got {delay!r}")
    d = int(math.floor(delay / h + 1e-12))
    f = max(0.0, delay - d * h)
    n = den.size - 1
    if n == 0:  # a static gain: acts one row later (left limit)
        b = np.zeros(d + 2)
        b[d + 1] = num[-1] / den[0]
        return b, np.array([1.0])
    A, B, C, D = signal.tf2ss(num, den)
    E_late, G_late = _zoh_integrals(A, B, h - f)  # the last h - f s of a period see the new value
    if f > 0:  # the first f s still see the old one
        E_early, G_f = _zoh_integrals(A, B, f)
        Phi, G_early = E_late @ E_early, E_late @ G_f
    else:
        Phi, G_early = E_late, np.zeros_like(G_late)
    a = np.poly(Phi)  # [1, a1, .., an]: det(zI - Phi) in powers of z^-1
    b = np.zeros(n + 2 + d)
    for gamma, shift in ((G_late, 0), (G_early, 1)):
        if not np.any(gamma):
            continue
        bn, _ = signal.ss2tf(Phi, gamma, C, np.zeros((1, 1)))
        b[d + shift: d + shift + n + 1] += bn[0]
    b[d + 1: d + 2 + n] += D[0, 0] * a  # the direct term, one row later
    return b, a


def simulate(num: np.ndarray, den: np.ndarray, h: float, u: np.ndarray, delay: float = 0.0) -> np.ndarray:
    """Sampled response of a continuous model to a piecewise-constant u (deviations)."""
    b, a = zoh_filter(num, den, h, delay)
    return signal.lfilter(b, a, u)


def d2c(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """The continuous (A_c, B_c) whose ZOH sampling at h gives (A, B): A_c = log(A)/h,
    B_c = A_c (A - I)^-1 B.  Refused when A has an eigenvalue on the negative real
    axis or at 0 (no real continuous model samples to it)."""
    ev = np.linalg.eigvals(A)
    if np.any((np.abs(ev.imag) < 1e-9) & (ev.real <= 1e-9)):
        raise IdentificationError("the sampled model has a pole on the negative real axis or at 0: "
                                  "no continuous-time model; try a lower order")
    Ac = np.real(linalg.logm(A)) / h
    n = A.shape[0]
    if np.allclose(A, np.eye(n)):
        return Ac, B / h
    # integral_0^h e^(Ac s) ds = Ac^-1 (A - I) when Ac is invertible; solve for B_c.
    integral = _zoh_integrals(Ac, np.eye(n), h)[1]
    Bc = np.linalg.solve(integral, B)
    return Ac, Bc
