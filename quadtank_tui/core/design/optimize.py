"""Ms-constrained PI and PID design (Andersson 3.2, after Panagopoulos 2000).

PI_opt: maximize ki = Kc/Ti subject to |1 + L(iw)| >= 1/Ms for all w.  With
L = (Kc + ki/(iw)) G(iw) = P - 1 + ki Q, P = 1 + Kc G, Q = G/(iw), the
constraint at one frequency is the quadratic |P + ki Q|^2 >= r^2 in ki (r = 1/Ms):
|Q|^2 ki^2 + 2 Re(P conj Q) ki + |P|^2 - r^2 >= 0.  Growing ki from 0, the first
frequency whose smaller root is reached stops it, so for a fixed Kc the largest
admissible ki is the minimum of those roots over a dense grid (exact on the
grid); then it is maximized over Kc (ki(Kc) is flat near its top, so Kc comes
out to a few 0.1 %).  The delay is exact: G(iw) includes e^(-iwL).

PID (this program's rule, "pid-ms"): the same problem with a derivative
Kc Td s/(1 + s Td/N) added to P, maximized over (Kc, Td) with the extra
constraint Td <= Ti/4, i.e. the PID's zeros stay real ("the series form").
Without an extra constraint the optimum puts a large derivative on a sharply
peaked sensitivity (Ti 14-25 % smaller and Td 58-75 % larger than Andersson's
PID_opt, control.md); Panagopoulos' own extra constraint is not given in the
thesis, so this one is stated instead, and every design is re-evaluated: its
Ms is checked against the spec.

Andersson's own PID_opt rows meet their Ms on their design models with an ideal
derivative (1.599-1.613 for Ms 1.6; tests/core/design), not with the N = 10 filter
his evaluation uses (up to 1.68); this rule designs with the filter in the loop.

A process with a negative gain is designed on -G and the gains negated.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize_scalar

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.pid_tuning import DERIVATIVE_FILTER_N, PIDTuning, DesignError
from quadtank_tui.core.design.frequency import frequency_grid
from quadtank_tui.core.design.sampled import derivative_shape, integral_shape, sample, sampled_grid

#: largest Td/Ti of the PID rule (real controller zeros).
TD_OVER_TI_MAX = 0.25
KC_GRID = 50
#: a loop gain this large meeting Ms means Ms does not bound it on this model
KC_UNBOUNDED = 1e9
UNBOUNDED = ("Ms alone does not bound the gains on this model (no dead time, no right-half-"
             "plane zero, phase above -180 deg): use lambda, or give the model a dead time")
TD_GRID = 16


def check_ms(ms: float) -> None:
    if not math.isfinite(ms) or ms <= 1.0:
        raise DesignError(f"Ms must be a number > 1 (max |S| >= 1 always), got {ms:g}")


def process_sign(g: DelayTF) -> float:
    """+1 or -1: the sign of the static (or velocity) gain; refuses a zero gain and
    an unstable model (the search grows ki from 0 along stable loops only)."""
    if np.any(g.poles().real > 1e-12):
        raise DesignError("Ms-constrained design needs a stable or integrating model; this one "
                          "has a pole in the right half-plane")
    k = g.static_gain
    if k == 0.0 or not math.isfinite(k):
        raise DesignError("the model has no static gain (a zero at s = 0): nothing for integral action to act on")
    return 1.0 if k > 0 else -1.0


def _ki_max(P: np.ndarray, Q: np.ndarray, r: float) -> np.ndarray:
    """Largest ki >= 0 keeping |P + ki Q| >= r at every column; rows are candidates.
    0 where a candidate already violates the constraint at ki = 0."""
    a = np.abs(Q) ** 2
    b = 2.0 * (P.real * Q.real + P.imag * Q.imag)
    c = np.abs(P) ** 2 - r * r
    disc = b * b - 4.0 * a * c
    binding = (disc > 0.0) & (b < 0.0)
    root = np.full(P.shape, np.inf)
    sq = np.sqrt(np.where(binding, disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        root = np.where(binding, 2.0 * c / (-b + sq), np.inf)
    out = root.min(axis=1)
    out[(c < 0.0).any(axis=1)] = 0.0
    return out


def _kc_limit(Gw: np.ndarray, D: np.ndarray, r: float) -> float:
    """Largest Kc with |1 + Kc D G| >= r everywhere (ki = 0): bisection."""
    lo, hi = 0.0, 1.0
    while np.all(np.abs(1.0 + hi * D * Gw) >= r):
        lo, hi = hi, hi * 2.0
        if hi > KC_UNBOUNDED:
            raise DesignError(UNBOUNDED)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if np.all(np.abs(1.0 + mid * D * Gw) >= r):
            lo = mid
        else:
            hi = mid
    return lo


def _best_kc(Gw: np.ndarray, Q: np.ndarray, D: np.ndarray, r: float) -> tuple[float, float]:
    """max over Kc of ki_max(Kc) for derivative shape D (1 for PI); returns (Kc, ki)."""
    kmax = _kc_limit(Gw, D, r)
    if kmax <= 0.0:
        return 0.0, 0.0
    kcs = np.linspace(0.0, kmax, KC_GRID + 1)[1:]
    ki = _ki_max(1.0 + np.outer(kcs, D * Gw), Q[None, :] * np.ones((len(kcs), 1)), r)
    i = int(np.argmax(ki))
    lo, hi = kcs[max(i - 1, 0)] if i > 0 else 0.0, kcs[min(i + 1, len(kcs) - 1)]

    def neg(kc: float) -> float:
        return -float(_ki_max((1.0 + kc * D * Gw)[None, :], Q[None, :], r)[0])

    res = minimize_scalar(neg, bounds=(lo, hi), method="bounded", options={"xatol": kmax * 1e-4})
    if -res.fun >= ki[i]:
        return float(res.x), float(-res.fun)
    return float(kcs[i]), float(ki[i])


def _loop_shapes(g: DelayTF, h: float, w: np.ndarray | None, sign: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(w, G, Q = G x the integral's shape): G(iw) and 1/(iw) for h = 0; for h > 0 the
    ZOH model G(e^(iwh)) and core.controllers.pid's forward-difference integral h/(z - 1), on
    0 < w < pi/h: the exact discrete-time design of the loop as it runs."""
    if h > 0.0:
        w = sampled_grid(g, h) if w is None else w[w < math.pi / h]
        Gw = sign * sample(g, h).freqresp(w)
        return w, Gw, Gw * integral_shape(h, w)
    w = frequency_grid(g) if w is None else w
    Gw = sign * g.freqresp(w)
    return w, Gw, Gw / (1j * w)


def pi_ms(g: DelayTF, ms: float, w: np.ndarray | None = None, h: float = 0.0) -> PIDTuning:
    """PI_opt: the PI with the largest ki = Kc/Ti whose loop keeps max|S| <= Ms
    (h > 0: the sampled loop's max|S|, see _loop_shapes)."""
    check_ms(ms)
    sign = process_sign(g)
    w, Gw, Q = _loop_shapes(g, h, w, sign)
    kc, ki = _best_kc(Gw, Q, np.ones_like(Gw), 1.0 / ms)
    if ki <= 0.0:
        raise DesignError(f"no PI meets Ms = {ms:g} on this model")
    return PIDTuning(sign * kc, kc / ki)


def _binding_frequency(Gw: np.ndarray, Q: np.ndarray, w: np.ndarray, kc: float, r: float) -> float:
    """The frequency whose constraint stops ki at this Kc (where the circle is touched)."""
    P = (1.0 + kc * Gw)[None, :]
    a, b = np.abs(Q) ** 2, 2.0 * (P.real * Q.real + P.imag * Q.imag)[0]
    c = (np.abs(P) ** 2 - r * r)[0]
    disc = b * b - 4.0 * a * c
    with np.errstate(divide="ignore", invalid="ignore"):
        root = np.where((disc > 0) & (b < 0), 2.0 * c / (-b + np.sqrt(np.maximum(disc, 0))), np.inf)
    return float(w[int(np.argmin(root))])


def pid_ms(g: DelayTF, ms: float, w: np.ndarray | None = None,
           n: float = DERIVATIVE_FILTER_N, td_over_ti_max: float = TD_OVER_TI_MAX, h: float = 0.0) -> PIDTuning:
    """This program's Ms-constrained PID: max ki over (Kc, Td), Td <= Ti/4 (see module).

    The search over Td runs on a band of 600 frequencies around the PI design's
    binding frequency; the chosen Td is then re-optimized over Kc on the full grid,
    so the constraint is met everywhere, not only on the band.  h > 0: the sampled
    loop, with core.controllers.pid's backward-difference derivative (see _loop_shapes)."""
    check_ms(ms)
    sign = process_sign(g)
    w, Gw, Q = _loop_shapes(g, h, w, sign)
    r = 1.0 / ms
    pi_kc, pi_ki = _best_kc(Gw, Q, np.ones_like(Gw), r)
    if pi_ki <= 0.0:
        raise DesignError(f"no PI or PID meets Ms = {ms:g} on this model")
    wb = _binding_frequency(Gw, Q, w, pi_kc, r)
    top = wb * 100.0 if h <= 0.0 else min(wb * 100.0, 0.9999 * math.pi / h)
    band = np.logspace(math.log10(wb / 100.0), math.log10(top), 600)
    _, Gb, Qb = _loop_shapes(g, h, band, sign)

    def design(td: float, gw: np.ndarray, q: np.ndarray, ww: np.ndarray) -> tuple[float, float]:
        D = (1.0 + td * 1j * ww / (1.0 + td * 1j * ww / n)) if h <= 0.0 else derivative_shape(td, n, h, ww)
        kc, ki = _best_kc(gw, q, D, r)
        if ki > 0.0 and td > td_over_ti_max * kc / ki:  # Ti = Kc/ki too short for Td:
            kc = _boundary_kc(gw, q, D, r, td, td_over_ti_max)  # stay on Td = c Ti
            ki = kc * td_over_ti_max / td
        return kc, ki

    ti_pi = pi_kc / pi_ki
    tds = np.linspace(0.0, ti_pi, TD_GRID + 1)[1:]
    scores = [design(float(td), Gb, Qb, band)[1] for td in tds]
    j = int(np.argmax(scores))
    td = float(tds[j])
    if scores[j] > pi_ki:
        step = float(tds[1] - tds[0])
        res = minimize_scalar(lambda x: -design(x, Gb, Qb, band)[1],
                              bounds=(max(td - step, step * 1e-3), td + step),
                              method="bounded", options={"xatol": step * 1e-2})
        if -res.fun > scores[j]:
            td = float(res.x)
        kc, ki = design(td, Gw, Q, w)
        if ki > pi_ki:
            return PIDTuning(sign * kc, kc / ki, td, n)
    return PIDTuning(sign * pi_kc, pi_kc / pi_ki)  # a derivative does not help on this model


def _boundary_kc(Gw: np.ndarray, Q: np.ndarray, D: np.ndarray, r: float,
                 td: float, c: float) -> float:
    """On Td = c Ti (ki = Kc c / Td): the largest Kc keeping |1 + L| >= r (bisection)."""

    def ok(kc: float) -> bool:
        return bool(np.all(np.abs(1.0 + kc * D * Gw + kc * c / td * Q) >= r))

    lo, hi = 0.0, _kc_limit(Gw, D, r)
    for _ in range(36):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo
