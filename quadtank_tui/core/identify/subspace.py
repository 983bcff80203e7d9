"""A MIMO state-space model by a subspace method (PO-MOESP, Verhaegen 1994), for
records in which both inputs move (Nunes 3.3 used Matlab's N4SID, the same family).

Why our own: the two libraries on PyPI do not fit.  nfoursid (MIT) pulls in pandas
and matplotlib and works on DataFrames; sippy-unipi is LGPL and pulls in casadi and
sympy.  PO-MOESP is forty lines of numpy: one LQ factorization of block-Hankel
matrices and one SVD.

    x_k+1 = A x_k + B u_k,   y_k = C x_k        (D = 0: y_k is read before u_k acts)

A and C come from the extended observability matrix (the SVD); B and the initial
state are then fitted to the simulated output by linear least squares (output
error, so noise does not bias them).  The model is converted to continuous time
(d2c) so that its gains, poles and zeros are in 1/s.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import signal

from quadtank_tui.core.identify import IdentificationError
from quadtank_tui.core.identify.sampling import d2c


@dataclass(frozen=True)
class SubspaceFit:
    """Continuous (A, B, C) in deviations from the operating point, the sampled
    (Ad, Bd), the singular values that suggest the order, the loss per output (mean
    square of y - ym), the initial state and output offset, and ym (deviations)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Ad: np.ndarray
    Bd: np.ndarray
    h: float
    singular_values: np.ndarray
    loss: np.ndarray
    x0: np.ndarray
    offset: np.ndarray
    ym: np.ndarray = field(repr=False)

    def simulate(self, du: np.ndarray) -> np.ndarray:
        """Output deviations for input deviations du (rows x inputs) from the fitted
        initial state and offset (the record's start)."""
        du = np.asarray(du, dtype=float)
        x = self.x0.copy()
        out = np.empty((du.shape[0], self.C.shape[0]))
        for k in range(du.shape[0]):
            out[k] = self.C @ x
            x = self.Ad @ x + self.Bd @ du[k]
        return out + self.offset


def _hankel(x: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """Block Hankel: block row r holds x[r:r+cols].T (x is samples x channels)."""
    return np.vstack([x[r:r + cols].T for r in range(rows)])


def fit_subspace(u: np.ndarray, y: np.ndarray, h: float, order: int = 4, block_rows: int = 10,
                 u0: np.ndarray | None = None, y0: np.ndarray | None = None) -> SubspaceFit:
    """PO-MOESP on a record (samples x inputs, samples x outputs) sampled every h s.
    Deviations are taken from u0, y0 (default: the first row, the operating point)."""
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    if u.ndim != 2 or y.ndim != 2 or u.shape[0] != y.shape[0]:
        raise IdentificationError("u and y must be (samples x channels) with one row count")
    N, m = u.shape
    p = y.shape[1]
    i = block_rows
    if not 1 <= order <= i * p:
        raise IdentificationError(f"order must be 1..{i * p}, got {order}")
    j = N - 2 * i + 1
    if j < 4 * (2 * i * (m + p)):
        raise IdentificationError(f"too few rows for a subspace model with {i} block rows: {N}")
    du = u - (u[0] if u0 is None else u0)
    dy = y - (y[0] if y0 is None else y0)
    if np.any(np.ptp(du, axis=0) == 0):
        raise IdentificationError("an input is constant: a MIMO model needs every input to move")
    U = _hankel(du, 2 * i, j)
    Y = _hankel(dy, 2 * i, j)
    Up, Uf, Yp, Yf = U[: i * m], U[i * m:], Y[: i * p], Y[i * p:]
    H = np.vstack([Uf, Up, Yp, Yf]) / np.sqrt(j)
    # numpy's stubs type every qr() as QRResult; mode="r" returns the array R alone.
    L = np.linalg.qr(H.T, mode="r").T  # type: ignore[attr-defined]  # H = L Q^T, L lower triangular
    a, b = i * m, i * m + i * (m + p)
    L32 = L[b:, a:b]  # the part of Yf explained by the past, with Uf projected out
    Us, s, _ = np.linalg.svd(L32)
    gamma = Us[:, :order] * np.sqrt(s[:order])
    C = gamma[:p]
    Ad = np.linalg.lstsq(gamma[:-p], gamma[p:], rcond=None)[0]
    Bd, x0, offset, ym = _fit_b(Ad, C, du, dy)
    A, B = d2c(Ad, Bd, h)
    loss = np.mean((dy - ym) ** 2, axis=0)
    return SubspaceFit(A, B, C, Ad, Bd, h, s[: max(order + 4, 8)], loss, x0, offset, ym)


def _fit_b(A: np.ndarray, C: np.ndarray, du: np.ndarray, dy: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """B, x0 and an output offset minimizing sum |y - ym|^2, ym the simulated output
    (linear in all three for given A, C)."""
    N, m = du.shape
    n, p = A.shape[0], C.shape[0]
    rows = np.zeros((N, p, n * m + n + p))
    delta = np.zeros(N + 1)
    delta[0] = 1.0
    for r in range(n):  # C (zI - A)^-1 e_r, one filter per state and output
        num, den = signal.ss2tf(A, np.eye(n)[:, r:r + 1], C, np.zeros((p, 1)))
        for o in range(p):
            for c in range(m):
                rows[:, o, c * n + r] = signal.lfilter(num[o], den, du[:, c])
            rows[:, o, n * m + r] = signal.lfilter(num[o], den, delta)[1:]  # C A^k e_r
    rows[:, :, n * m + n:] = np.eye(p)
    X = rows.reshape(N * p, -1)
    theta, *_ = np.linalg.lstsq(X, dy.reshape(-1), rcond=None)
    B = theta[: n * m].reshape(m, n).T
    ym = (X @ theta).reshape(N, p)
    return B, theta[n * m: n * m + n], theta[n * m + n:], ym
