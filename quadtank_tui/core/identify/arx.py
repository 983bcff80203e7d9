"""ARX by least squares, per element: the quick equation-error model of Nunes 3.3.

    y_k + a_1 y_k-1 + ... + a_na y_k-na = b_1 u_k-nk + ... + b_nb u_k-nk-nb+1 + e_k

Biased when the output carries noise that is not filtered by 1/A (almost always):
on the tank data its gains can be far off, which is why the output-error fit is the
default.  Kept because it is fast, needs no starting values, and shows the bias.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import numpy as np
import numpy.typing as npt
from scipy import signal

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.identify import IdentificationError
from quadtank_tui.core.identify.sampling import d2c


@dataclass(frozen=True)
class ARXFit:
    """Polynomials in z^-1 (a with a_0 = 1, b with nk leading zeros), the sampled
    model's continuous equivalent (None when a pole on the negative real axis leaves
    it none: a biased fit often has one), the simulated output ym and its loss."""

    a: np.ndarray
    b: np.ndarray
    h: float
    tf: DelayTF | None
    loss: float
    ym: np.ndarray = field(repr=False)

    @property
    def static_gain(self) -> float:
        return float(self.b.sum() / self.a.sum())


def fit_arx(u: npt.ArrayLike, y: npt.ArrayLike, h: float, na: int = 1, nb: int = 1, nk: int = 1,
            u0: float | None = None, y0: float | None = None) -> ARXFit:
    """Least squares on deviations from the rest values (default: the first row)."""
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    if na < 1 or nb < 1 or nk < 1:
        raise IdentificationError("ARX orders na, nb and the delay nk must be >= 1")
    start = max(na, nb + nk - 1)
    if u.size < start + 10 * (na + nb):
        raise IdentificationError(f"too few rows for ARX({na}, {nb}, {nk}): {u.size}")
    du = u - (u[0] if u0 is None else u0)
    y_rest = float(y[0] if y0 is None else y0)
    dy = y - y_rest
    if np.ptp(du) == 0:
        raise IdentificationError("the input is constant: nothing to identify from")
    rows = np.arange(start, u.size)
    X = np.column_stack([-dy[rows - i] for i in range(1, na + 1)]
                        + [du[rows - nk - i] for i in range(nb)])
    theta, *_ = np.linalg.lstsq(X, dy[rows], rcond=None)
    a = np.r_[1.0, theta[:na]]
    b = np.r_[np.zeros(nk), theta[na:]]
    ym = y_rest + signal.lfilter(b, a, du)
    try:
        tf: DelayTF | None = _continuous(a, b, h)
    except IdentificationError:
        tf = None
    return ARXFit(a, b, h, tf, float(np.mean((y - ym) ** 2)), ym)


def _continuous(a: np.ndarray, b: np.ndarray, h: float) -> DelayTF:
    """B(z)/A(z) with its whole-sample delay beyond one as a dead time, the rest
    through d2c (a ZOH-equivalent continuous model)."""
    nk = int(np.argmax(b != 0)) if np.any(b) else 1
    bb = b[nk - 1:] if nk >= 1 else b
    n = max(a.size, bb.size) - 1
    a_pad = np.r_[a, np.zeros(n + 1 - a.size)]
    b_pad = np.r_[bb, np.zeros(n + 1 - bb.size)]
    # Padded to one length, powers of z^-1 read as powers of z.
    A, B, C, D = signal.tf2ss(np.trim_zeros(b_pad, "f"), a_pad)
    Ac, Bc = d2c(A, B, h)
    num, den = signal.ss2tf(Ac, Bc, C, D)
    num = np.trim_zeros(np.where(np.abs(num[0]) < 1e-14 * np.abs(num[0]).max(), 0.0, num[0]), "f")
    return DelayTF(tuple(num), tuple(den), max(0, nk - 1) * h)
