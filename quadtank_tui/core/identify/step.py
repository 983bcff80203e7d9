"""Step-response models (Andersson 2000, section 2.1): five structures, their
closed-form step responses, steps found in u, and a least-squares fit.

    1  K / (sT + 1)^n e^-sL              (n = 1..4)
    2  K (sTz + 1) / (sT + 1)^n e^-sL
    3  K / s e^-sL
    4  K / (s (sT + 1)) e^-sL
    5  K (sTz + 1) / (s (sT + 1)) e^-sL

Several steps in one record superpose; the model output is
``y0 (+ k0 t for 3..5) + sum_j A_j y_s(t - t_j)``.  Because the input of a sampled
record is piecewise constant, the sum is the exact response of the continuous model
to any such input (a PRBS too), not an approximation.

The fit minimizes Andersson's loss sum (y - ym)^2 / N.  For a given time constant T
and delay L the output is linear in K, K Tz, y0 and k0, so these are solved exactly
(variable projection) and only T and L are searched: a coarse grid, then
scipy.optimize.least_squares from the best points (or from the user's T and L).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.identify import IdentificationError

STRUCTURES: dict[int, str] = {
    1: "K/(sT+1)^n e^-sL",
    2: "K(sTz+1)/(sT+1)^n e^-sL",
    3: "K/s e^-sL",
    4: "K/(s(sT+1)) e^-sL",
    5: "K(sTz+1)/(s(sT+1)) e^-sL",
}
INTEGRATING = frozenset({3, 4, 5})
HAS_T = frozenset({1, 2, 4, 5})
HAS_TZ = frozenset({2, 5})
HAS_N = frozenset({1, 2})
N_MAX = 4
#: Andersson's FindSteps default: a step is a change above 5 % of max(u) - min(u).
STEP_SENS = 0.05


@dataclass(frozen=True)
class StepModel:
    """One of the five structures with its parameters (s; K in output/input units,
    a velocity gain 1/s for the integrating ones)."""

    structure: int
    K: float
    T: float = 0.0
    Tz: float = 0.0
    n: int = 1
    L: float = 0.0

    def __post_init__(self) -> None:
        if self.structure not in STRUCTURES:
            raise IdentificationError(f"structure must be 1..5, got {self.structure!r}")
        if self.structure in HAS_N and not 1 <= self.n <= N_MAX:
            raise IdentificationError(f"n must be 1..{N_MAX}, got {self.n!r}")
        if self.structure in HAS_T and not self.T > 0:
            raise IdentificationError(f"T must be > 0 s, got {self.T!r}")
        if not (math.isfinite(self.L) and self.L >= 0):
            raise IdentificationError(f"L must be >= 0 s, got {self.L!r}")

    def tf(self) -> DelayTF:
        """The model as a DelayTF (descending powers of s, exact delay)."""
        s = self.structure
        lag = np.poly1d([self.T, 1.0]) ** (self.n if s in HAS_N else 1)
        num = (self.K * self.Tz, self.K) if s in HAS_TZ else (self.K,)
        if s in (1, 2):
            den = tuple(lag.coeffs)
        elif s == 3:
            den = (1.0, 0.0)
        else:
            den = (self.T, 1.0, 0.0)
        return DelayTF(num, den, self.L)

    def params(self) -> dict[str, float]:
        """The structure's own parameters by name (K, T, Tz, n, L)."""
        s = self.structure
        out: dict[str, float] = {"K": self.K}
        if s in HAS_T:
            out["T"] = self.T
        if s in HAS_TZ:
            out["Tz"] = self.Tz
        if s in HAS_N:
            out["n"] = self.n
        out["L"] = self.L
        return out

    def step_response(self, t: npt.ArrayLike) -> np.ndarray:
        """Response to a unit step at t = 0 (zero up to and at t = L)."""
        tau = np.asarray(t, dtype=float) - self.L
        parts = _basis(self.structure, self.n, tau, self.T)
        return sum((c * b for c, b in zip((self.K, self.K * self.Tz), parts)), np.zeros_like(tau))

    def __str__(self) -> str:
        p = self.params()
        return f"{STRUCTURES[self.structure]}: " + "  ".join(
            f"{k}={v:d}" if k == "n" else f"{k}={v:.5g}" for k, v in p.items())


def _basis(structure: int, n: int, tau: np.ndarray, T: float) -> list[np.ndarray]:
    """Closed-form unit-step responses split into the parts that multiply K and K Tz
    (Andersson 2.1.3).  tau = t - L; every part is 0 for tau <= 0."""
    pos = tau > 0
    tp = np.where(pos, tau, 0.0)
    if structure == 3:
        return [tp]
    x = tp / T
    e = np.exp(-x)
    if structure in (4, 5):
        parts: list[np.ndarray] = [np.where(pos, tp - T * (1 - e), 0.0)]
        if structure == 5:
            parts.append(np.where(pos, 1 - e, 0.0))
        return parts
    term = np.ones_like(x)
    total = np.ones_like(x)
    for k in range(1, n):
        term = term * x / k
        total = total + term
    parts = [np.where(pos, 1 - e * total, 0.0)]
    if structure == 2:  # Tz times the impulse response of 1/(sT+1)^n
        parts.append(np.where(pos, e * term / T, 0.0))
    return parts


# --- steps ------------------------------------------------------------------------------

@dataclass(frozen=True)
class Steps:
    """Steps found in u: `index` of the first sample at the new level, `size`."""

    index: np.ndarray
    size: np.ndarray
    u0: float  # the level before the first step


def find_steps(u: npt.ArrayLike, sens: float = STEP_SENS) -> Steps:
    """Andersson's FindSteps (5.6.1): a step starts where two following samples
    differ by more than `sens` (max(u) - min(u)); its size is measured when u has
    settled (a difference below a tenth of that) from the level before."""
    u = np.asarray(u, dtype=float)
    if u.size < 2:
        raise IdentificationError("too few rows to find a step (need at least 2)")
    span = float(u.max() - u.min())
    if span == 0.0:
        raise IdentificationError("the input is constant: no step to identify from")
    big, small = sens * span, 0.1 * sens * span
    d = np.abs(np.diff(u))
    index, size = [], []
    level = float(u[0])
    k = 0
    while k < d.size:
        if d[k] > big:
            c = k + 1
            while c < d.size and d[c] >= small:
                c += 1
            index.append(k + 1)
            size.append(float(u[c]) - level)
            level = float(u[c])
            k = c
        k += 1
    return Steps(np.array(index, dtype=int), np.array(size), float(u[0]))


# --- fitting ----------------------------------------------------------------------------

@dataclass(frozen=True)
class StepFit:
    """A fitted step model with its initial value y0, initial slope k0 (integrating
    structures; else 0), loss sum (y - ym)^2 / N and the model output ym."""

    model: StepModel
    y0: float
    k0: float
    loss: float
    ym: np.ndarray = field(repr=False)
    steps: Steps = field(repr=False)


def _superpose(g: np.ndarray, steps: Steps) -> np.ndarray:
    """sum_j A_j g[k - index_j]: the records are uniformly sampled, so every step's
    response is the same sequence g (the basis at tau = k h - L), shifted."""
    out = np.zeros_like(g)
    n = g.size
    for i, a in zip(steps.index, steps.size):
        out[i:] += a * g[: n - i]
    return out


def _design(structure: int, n: int, h: float, size: int, steps: Steps, T: float, L: float) -> np.ndarray:
    """Columns: 1, [t], then each basis part summed over the steps (times A_j)."""
    k = np.arange(size) * h
    cols: list[np.ndarray] = [np.ones(size)]
    if structure in INTEGRATING:
        cols.append(k)
    for part in _basis(structure, n, k - L, T):
        cols.append(_superpose(part, steps))
    return np.column_stack(cols)


def _solve(structure: int, n: int, h: float, y: np.ndarray, steps: Steps, T: float, L: float
           ) -> tuple[np.ndarray, np.ndarray]:
    X = _design(structure, n, h, y.size, steps, T, L)
    c, *_ = np.linalg.lstsq(X, y, rcond=None)
    return c, X @ c


def fit_step(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    h: float,
    structure: int = 1,
    n: int | None = None,
    *,
    start: dict[str, float] | None = None,
    steps: Steps | None = None,
    sens: float = STEP_SENS,
    cancel: Callable[[], bool] | None = None,
) -> StepFit:
    """Fit `structure` to a record sampled every `h` s (u input, y output).  `n` None tries 1..4
    (structures 1 and 2) and keeps the smallest loss.  `start` gives starting T and
    L (K, Tz, y0 and k0 need none: they are solved exactly).  `cancel()` returning
    True stops between trials."""
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    if not (u.shape == y.shape and u.ndim == 1):
        raise IdentificationError("u and y must be vectors of one length")
    if u.size < 10:
        raise IdentificationError(f"too few rows to fit a model: {u.size} (need at least 10)")
    if not (math.isfinite(h) and h > 0):
        raise IdentificationError(f"the sampling time must be > 0 s, got {h!r}")
    if structure not in STRUCTURES:
        raise IdentificationError(f"structure must be 1..5, got {structure!r}")
    steps = steps if steps is not None else find_steps(u, sens)
    if steps.index.size == 0:
        raise IdentificationError("no step found in the input")
    orders = [1] if structure not in HAS_N else ([n] if n is not None else list(range(1, N_MAX + 1)))
    best: StepFit | None = None
    for order in orders:
        if cancel is not None and cancel():
            break
        fit = _fit_order(h, y, structure, order, steps, start or {})
        if best is None or fit.loss < best.loss:
            best = fit
    if best is None:
        raise IdentificationError("cancelled")
    return best


def _fit_order(h: float, y: np.ndarray, structure: int, n: int, steps: Steps,
               start: dict[str, float]) -> StepFit:
    span = (y.size - 1) * h
    # Delay bound: a delay longer than the data after the first step explains nothing.
    L_max = max(h, 0.5 * (y.size - 1 - steps.index[0]) * h)
    T_lo, T_hi = 0.05 * h, 5.0 * span
    has_T = structure in HAS_T

    def unpack(p: np.ndarray) -> tuple[float, float]:
        return (math.exp(p[0]), p[1]) if has_T else (1.0, p[0])

    def residual(p: np.ndarray) -> np.ndarray:
        T, L = unpack(p)
        return _solve(structure, n, h, y, steps, T, L)[1] - y

    if "T" in start or "L" in start:
        T0 = float(start.get("T", span / 20))
        L0 = float(start.get("L", 0.0))
        if has_T and not T0 > 0:
            raise IdentificationError(f"starting T must be > 0 s, got {T0!r}")
        candidates = [(T0, min(max(L0, 0.0), L_max))]
    else:
        T_grid = np.geomspace(max(T_lo, 0.2 * h), span / 4, 9) if has_T else [1.0]
        L_grid = np.unique(np.minimum(L_max, [0.0, h, 4 * h, 0.02 * span, 0.06 * span]))
        scored = sorted(
            (float(np.sum(residual(np.array([math.log(T), L] if has_T else [L])) ** 2)), T, L)
            for T in T_grid for L in L_grid
        )
        candidates = [(T, L) for _, T, L in scored[:3]]
    lo = [math.log(T_lo), 0.0] if has_T else [0.0]
    hi = [math.log(T_hi), L_max] if has_T else [L_max]
    best = None
    for T0, L0 in candidates:
        p0 = np.array([math.log(min(max(T0, T_lo), T_hi)), L0] if has_T else [L0])
        r = least_squares(residual, p0, bounds=(lo, hi), x_scale=[1.0, max(h, 0.01 * span)][-p0.size:],
                          diff_step=1e-7, xtol=1e-10, ftol=1e-12, gtol=1e-12, max_nfev=200)
        if best is None or r.cost < best.cost:
            best = r
    assert best is not None
    T, L = unpack(best.x)
    c, ym = _solve(structure, n, h, y, steps, T, L)
    i = 1
    y0 = float(c[0])
    k0 = 0.0
    if structure in INTEGRATING:
        k0, i = float(c[1]), 2
    K = float(c[i])
    Tz = float(c[i + 1]) / K if structure in HAS_TZ and K != 0 else 0.0
    model = StepModel(structure, K, T if has_T else 0.0, Tz, n, L)
    loss = float(np.mean((y - ym) ** 2))
    return StepFit(model, y0, k0, loss, ym, steps)


def simulate_steps(model: StepModel, h: float, size: int, steps: Steps, y0: float = 0.0, k0: float = 0.0
                   ) -> np.ndarray:
    """The model output over `size` samples every `h` s for the steps of a record:
    y0 + k0 t + sum_j A_j y_s(t - t_j)."""
    t = np.arange(size) * h
    out = y0 + (k0 * t if model.structure in INTEGRATING else 0.0)
    return out + _superpose(model.step_response(t), steps)
