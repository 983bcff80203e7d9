"""Frequency-domain figures of a loop L(s) = Gy(s) G(s) e^(-sL): Ms, gain and phase
margins, delay margin, crossover, and closed-loop stability by the Nyquist
criterion (the delay exact, no Pade approximation).

The phase is computed term by term, sum(arg(iw - z)) - sum(arg(iw - p)) - w L,
so it is continuous in w with no unwrapping guesses; margins follow Andersson
4.3.2 (Am = 1/|L(i wp)| where the phase crosses -180 deg; Lm = phi_m / wc).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from quadtank_tui.core.delaytf import DelayTF

GRID_POINTS = 4000
#: gain margins above this are reported as infinite (crossings where |L| < 1e-4).
MAX_GAIN_MARGIN = 1e4


def characteristic_frequencies(g: DelayTF) -> np.ndarray:
    """|poles|, |zeros| (nonzero) and 1/delay: where the loop's shape changes (rad/s)."""
    roots = np.concatenate([g.poles(), g.zeros()])
    f = [abs(r) for r in roots if abs(r) > 1e-12]
    if g.delay > 0.0:
        f.append(1.0 / g.delay)
    return np.array(f or [1.0])


def frequency_grid(*models: DelayTF, points: int = GRID_POINTS, decades: float = 3.0) -> np.ndarray:
    """A log grid covering every model's characteristic frequencies +- `decades`."""
    f = np.concatenate([characteristic_frequencies(m) for m in models])
    lo, hi = f.min() * 10.0 ** -decades, f.max() * 10.0 ** decades
    return np.logspace(math.log10(lo), math.log10(hi), points)


def phase(loop: DelayTF, w: np.ndarray | float,
          roots: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Continuous phase (rad) of loop(i w), w > 0; a negative gain counts as -pi.
    `roots` = (zeros, poles) if already known."""
    w = np.asarray(w, dtype=float)
    s = 1j * w
    zeros, poles = roots if roots is not None else (loop.zeros(), loop.poles())
    ph = np.zeros_like(w) - w * loop.delay
    for z in zeros:
        ph = ph + np.angle(s - z)
    for p in poles:
        ph = ph - np.angle(s - p)
    lead = loop.num[0] / loop.den[0]
    return ph + (-math.pi if lead < 0 else 0.0)


@dataclass(frozen=True)
class Margins:
    """Andersson's stability figures; inf where a crossing does not exist."""

    Ms: float
    w_ms: float
    phase_margin_deg: float
    crossover: float
    gain_margin: float
    phase_crossover: float
    delay_margin: float
    stable: bool


def _refine_max(f, w: np.ndarray, i: int) -> tuple[float, float]:
    """Maximize f(w) near grid point i (log w); returns (w, f)."""
    lo, hi = w[max(i - 1, 0)], w[min(i + 1, len(w) - 1)]
    if lo == hi:
        return w[i], f(w[i])
    res = minimize_scalar(lambda x: -f(math.exp(x)), bounds=(math.log(lo), math.log(hi)),
                          method="bounded", options={"xatol": 1e-10})
    best = float(math.exp(res.x))
    return (best, -res.fun) if -res.fun >= f(w[i]) else (w[i], f(w[i]))


def sensitivity_peak(loop: DelayTF, w: np.ndarray) -> tuple[float, float]:
    """(Ms, w at Ms): max |1/(1 + L(iw))|, refined between grid points."""
    s = np.abs(1.0 / (1.0 + loop.freqresp(w)))
    i = int(np.argmax(s))
    wm, ms = _refine_max(lambda x: float(abs(1.0 / (1.0 + loop.freqresp(x)))), w, i)
    return ms, wm


def crossings(f, w: np.ndarray, values: np.ndarray) -> list[float]:
    """Roots of f on w where `values` (f on the grid) changes sign: with f = log|L|,
    the gain crossovers (this module's margins and core.icad's channels)."""
    out = []
    for i in np.nonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0)[0]:
        out.append(brentq(f, w[i], w[i + 1], xtol=1e-14 * w[i], rtol=1e-12))
    return out


def phase_crossings(phase_at, w: np.ndarray, ph: np.ndarray, where: np.ndarray | None = None) -> list[float]:
    """Frequencies where the continuous phase `ph` (phase_at on the grid, rad)
    crosses -180 deg - k 360 deg, refined by root finding; `where` (one flag per
    grid interval) keeps only some intervals."""
    k = np.floor((ph + math.pi) / (2.0 * math.pi))
    cross = np.diff(k) != 0
    out = []
    for i in np.nonzero(cross if where is None else cross & where)[0]:
        target = -math.pi + 2.0 * math.pi * max(k[i], k[i + 1])
        out.append(brentq(lambda v: float(phase_at(v)) - target, w[i], w[i + 1], xtol=1e-14 * w[i]))
    return out


def is_stable(loop: DelayTF, w: np.ndarray | None = None) -> bool:
    """Nyquist: closed loop 1/(1 + L) stable?  Counts the winding of 1 + L(iw) over
    w > 0, closes it by symmetry and the indentation around the integrators, and
    compares with the open-loop poles in the right half-plane."""
    poles = loop.poles()
    n_int = loop.integrators
    if np.any((np.abs(poles.real) < 1e-12) & (np.abs(poles) > 1e-12)):
        return False  # poles on the imaginary axis away from 0: marginal at best
    p_rhp = int(np.sum(poles.real > 1e-12))
    if w is None:
        w = frequency_grid(loop, points=GRID_POINTS, decades=4.0)
    hi = w[-1]
    num0, den0 = loop.num[0], loop.den[0]
    if len(loop.num) == len(loop.den) and abs(num0 / den0) >= 1.0 and loop.delay > 0.0:
        return False  # |L(inf)| >= 1 with a delay: infinitely many circles around -1
    while abs(loop.freqresp(hi)) > 0.2 and hi < w[-1] * 1e6 and len(loop.num) < len(loop.den):
        hi *= 10.0
    if hi > w[-1]:
        w = np.concatenate([w, np.logspace(math.log10(w[-1]), math.log10(hi), 400)[1:]])
    w = np.asarray(w, dtype=float)
    for _ in range(12):  # refine until the argument of 1 + L moves < 0.5 rad a step
        arg = np.angle(1.0 + loop.freqresp(w))
        step = np.abs(np.diff(np.unwrap(arg)))
        bad = np.nonzero(step > 0.5)[0]
        if len(bad) == 0:
            break
        mids = np.sqrt(w[bad] * w[bad + 1])
        w = np.sort(np.concatenate([w, mids]))
    unwrapped = np.unwrap(np.angle(1.0 + loop.freqresp(w)))
    delta = unwrapped[-1] - unwrapped[0]
    ccw = (2.0 * delta - n_int * math.pi) / (2.0 * math.pi)
    return round(p_rhp - ccw) == 0


def margins(loop: DelayTF, w: np.ndarray | None = None) -> Margins:
    """Ms, phase/gain/delay margins and crossovers of `loop` on grid `w` (refined)."""
    if w is None:
        w = frequency_grid(loop)
    stable = is_stable(loop)
    ms, w_ms = sensitivity_peak(loop, w)
    if not stable:
        ms = math.inf
    roots = (loop.zeros(), loop.poles())
    mag = np.abs(loop.freqresp(w))
    gains = crossings(lambda x: math.log(abs(loop.freqresp(x))), w, np.log(mag))
    pm, wc = math.inf, math.nan
    for x in gains:  # the smallest phase margin counts
        m = (math.degrees(float(phase(loop, x, roots))) + 180.0 + 180.0) % 360.0 - 180.0
        if m < pm:
            pm, wc = m, x
    ph = phase(loop, w, roots)
    am, wp = math.inf, math.nan
    # phase crossings of -180 - k 360 deg where |L| > 1/MAX_GAIN_MARGIN
    for x in phase_crossings(lambda v: phase(loop, v, roots), w, ph, mag[:-1] > 1.0 / MAX_GAIN_MARGIN):
        a = 1.0 / abs(loop.freqresp(x))
        if a < am:
            am, wp = a, x
    lm = math.radians(pm) / wc if math.isfinite(pm) and wc > 0 else math.inf
    return Margins(ms, w_ms, pm, wc, am, wp, lm, stable)
