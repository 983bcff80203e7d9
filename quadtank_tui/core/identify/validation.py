"""Data quality and model validation (Nunes 3.2-3.3; Ljung's residual tests).

- identification / validation split (default halves);
- fit in percent, NRMSE: 100 (1 - |y - ym| / |y - mean(y)|) on the validation part;
- residual autocorrelation and input-residual cross-correlation with the 99 %
  confidence band 2.576 / sqrt(N): a model that extracted everything keeps them inside;
- coherence |S_uy| / sqrt(S_uu S_yy) (Nunes' definition: the square root of what
  scipy.signal.coherence returns) and the spectral estimate G(iw) = S_uy / S_uu, both
  with a Hamming window of 720 points as in the thesis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from quadtank_tui.core.identify import IdentificationError

#: Two-sided 99 % point of the normal distribution.
Z99 = 2.5758293035489
WINDOW = 720
LAGS = 25


def split_index(rows: int, fraction: float = 0.5) -> int:
    """First row of the validation part: the identification part is `fraction` of the
    rows (0 < fraction <= 1; 1 validates on the identification data itself)."""
    if not 0.0 < fraction <= 1.0:
        raise IdentificationError(f"the identification fraction must be in (0, 1], got {fraction:g}")
    k = int(round(rows * fraction))
    if k < 10:
        raise IdentificationError(f"too few rows to identify from: {k} of {rows}")
    return k if k < rows else 0


def fit_percent(y: np.ndarray, ym: np.ndarray) -> float:
    """NRMSE fit: 100 for a perfect model, 0 for the mean, negative when worse."""
    y = np.asarray(y, dtype=float)
    ref = np.linalg.norm(y - y.mean())
    if ref == 0.0:
        return 100.0 if np.allclose(y, ym) else -np.inf
    return float(100.0 * (1.0 - np.linalg.norm(y - np.asarray(ym)) / ref))


@dataclass(frozen=True)
class Correlation:
    """Normalized correlation at `lags`, the 99 % band, and the share inside it."""

    lags: np.ndarray
    value: np.ndarray
    band: float

    @property
    def inside(self) -> float:
        """Fraction of the tested lags inside the band (lag 0 of an autocorrelation,
        1 by definition, is not tested)."""
        test = self.lags != 0 if self.lags.min() >= 0 else np.ones_like(self.lags, dtype=bool)
        return float(np.mean(np.abs(self.value[test]) <= self.band))


def _xcorr(a: np.ndarray, b: np.ndarray, lag: int) -> float:
    """sum_k a_k+lag b_k / N (a leads b by `lag` samples)."""
    n = a.size
    return float(a[lag:] @ b[: n - lag]) / n if lag >= 0 else float(a[: n + lag] @ b[-lag:]) / n


def autocorrelation(e: np.ndarray, lags: int = LAGS) -> Correlation:
    e = np.asarray(e, dtype=float) - np.mean(e)
    r0 = _xcorr(e, e, 0)
    if r0 == 0.0:
        raise IdentificationError("the residuals are all zero: nothing to test")
    k = np.arange(lags + 1)
    return Correlation(k, np.array([_xcorr(e, e, int(i)) / r0 for i in k]), Z99 / np.sqrt(e.size))


def cross_correlation(u: np.ndarray, e: np.ndarray, lags: int = LAGS) -> Correlation:
    """R_ue(tau) = E e(t + tau) u(t), tau = -lags..lags, normalized by the standard
    deviations; for tau > 0 a value outside the band means input the model missed."""
    u = np.asarray(u, dtype=float) - np.mean(u)
    e = np.asarray(e, dtype=float) - np.mean(e)
    scale = np.sqrt(_xcorr(u, u, 0) * _xcorr(e, e, 0))
    if scale == 0.0:
        raise IdentificationError("a constant input or zero residuals: no cross-correlation")
    k = np.arange(-lags, lags + 1)
    return Correlation(k, np.array([_xcorr(e, u, int(i)) / scale for i in k]), Z99 / np.sqrt(e.size))


def _segment(n: int, window: int) -> int:
    if n < 8:
        raise IdentificationError(f"too few rows for a spectral estimate: {n}")
    return min(window, n)


def coherence(u: np.ndarray, y: np.ndarray, h: float, window: int = WINDOW) -> tuple[np.ndarray, np.ndarray]:
    """(frequency in Hz, coherence in [0, 1]) with a Hamming window of `window` points."""
    nper = _segment(len(u), window)
    f, msc = signal.coherence(u, y, fs=1.0 / h, window="hamming", nperseg=nper, detrend="constant")
    return f, np.sqrt(np.clip(msc, 0.0, 1.0))


def spectral_estimate(u: np.ndarray, y: np.ndarray, h: float, window: int = WINDOW
                      ) -> tuple[np.ndarray, np.ndarray]:
    """(frequency in rad/s, G(iw) = S_uy / S_uu): the frequency response read off the
    data, to check a parametric model against."""
    nper = _segment(len(u), window)
    f, suu = signal.welch(u, fs=1.0 / h, window="hamming", nperseg=nper, detrend="constant")
    _, suy = signal.csd(u, y, fs=1.0 / h, window="hamming", nperseg=nper, detrend="constant")
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.where(suu > 0, suy / suu, np.nan)
    return 2 * np.pi * f, g
