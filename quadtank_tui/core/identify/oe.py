"""Output-error fits of low-order continuous transfer functions (one element, SISO).

    G(s) = (b_m s^m + ... + b_0) / ((1 + s T_1) ... (1 + s T_n)) e^(-s L)

The model output is the ZOH-sampled response to the measured input (never the
measured output: equation-error methods such as ARX are biased when the output is
noisy, see ``arx.py``).  For given time constants and delay the output is linear in
the numerator and in the output's rest value, so those are solved exactly
(variable projection) and only T_1..T_n and L are searched: a grid, then
scipy.optimize.least_squares.  Real poles only (the tank process has no others); a
model with complex poles comes from the subspace fit.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.identify import IdentificationError
from quadtank_tui.core.identify.sampling import simulate

ORDER_MAX = 4


@dataclass(frozen=True)
class OEModel:
    """num(s) / prod(1 + s T_k) e^(-s L); num descending in s, T_k > 0 (s)."""

    num: tuple[float, ...]
    T: tuple[float, ...]
    L: float = 0.0

    @property
    def den(self) -> tuple[float, ...]:
        return tuple(_den(self.T))

    @property
    def K(self) -> float:
        """The static gain (output units per input unit)."""
        return self.num[-1]

    @property
    def Tz(self) -> tuple[float, ...]:
        """Zero time constants, num = K prod(1 + s Tz): Tz < 0 is a right half-plane
        zero; empty when the numerator has complex roots or K = 0."""
        roots = np.roots(self.num) if len(self.num) > 1 else np.zeros(0)
        if self.K == 0 or np.any(np.abs(roots.imag) > 1e-12 * np.maximum(1, abs(roots))):
            return ()
        return tuple(sorted(float(-1 / r.real) for r in roots))

    def tf(self) -> DelayTF:
        return DelayTF(self.num, self.den, self.L)

    def params(self) -> dict[str, object]:
        return {"K": self.K, "T": list(self.T), "Tz": list(self.Tz), "L": self.L}

    def __str__(self) -> str:
        zeros = "".join(f"(1{tz:+.3g}s)" for tz in self.Tz)
        if len(self.num) > 1 and not zeros:
            zeros = "(" + " ".join(f"{c:+.4g}" for c in np.asarray(self.num) / self.K) + ")"
        poles = "".join(f"(1+{T:.3g}s)" for T in self.T)
        delay = f" e^-{self.L:.3g}s" if self.L > 1e-6 else ""
        return f"{self.K:.4g}{zeros}/{poles}{delay}"


@dataclass(frozen=True)
class OEFit:
    """A fitted model, the output's rest value, the loss sum (y - ym)^2 / N, ym."""

    model: OEModel
    offset: float
    loss: float
    ym: np.ndarray = field(repr=False)


def _den(T: Sequence[float]) -> np.ndarray:
    den = np.array([1.0])
    for Tk in T:
        den = np.polymul(den, [Tk, 1.0])
    return den


def _columns(du: np.ndarray, h: float, T: Sequence[float], L: float, nz: int) -> list[np.ndarray]:
    """The response to s^i / den(s) for i = nz..0: the output is linear in num."""
    den = _den(T)
    cols = []
    for i in range(nz, -1, -1):
        num = np.zeros(i + 1)
        num[0] = 1.0
        cols.append(simulate(num, den, h, du, L))
    return cols


def _design(du: np.ndarray, h: float, T: Sequence[float], L: float, nz: int) -> np.ndarray:
    """Columns: the response to s^i / den(s) for i = nz..0, then 1 (the rest value)."""
    return np.column_stack(_columns(du, h, T, L, nz) + [np.ones_like(du)])


def fit_oe(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    h: float,
    order: int = 1,
    zeros: int = 0,
    *,
    delay: bool = True,
    u0: float | None = None,
    start: Mapping[str, Any] | None = None,
) -> OEFit:
    """Fit `order` real poles and `zeros` zeros (0 <= zeros < order) to a record
    sampled every `h` s.  `u0` is the input's rest value (default u[0]: the rows
    start at the operating point).  `delay` False keeps L = 0.  `start` may give
    "T" (a number or a list, one per pole) and "L": user values, each read with float()."""
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    if u.shape != y.shape or u.ndim != 1:
        raise IdentificationError("u and y must be vectors of one length")
    if not 1 <= order <= ORDER_MAX:
        raise IdentificationError(f"order must be 1..{ORDER_MAX}, got {order}")
    if not 0 <= zeros < order:
        raise IdentificationError(f"zeros must be 0..{order - 1} for order {order}, got {zeros}")
    if u.size < 10 * (order + zeros + 2):
        raise IdentificationError(f"too few rows for an order-{order} model: {u.size}")
    du = u - (u[0] if u0 is None else u0)
    if np.ptp(du) == 0:
        raise IdentificationError("the input is constant: nothing to identify from")
    span = (u.size - 1) * h
    lo_T, hi_T = math.log(0.05 * h), math.log(5 * span)
    L_max = 0.25 * span

    def unpack(p: np.ndarray) -> tuple[list[float], float]:
        return [math.exp(x) for x in p[:order]], (float(p[order]) if delay else 0.0)

    def residual(p: np.ndarray) -> np.ndarray:
        T, L = unpack(p)
        X = _design(du, h, T, L, zeros)
        c, *_ = np.linalg.lstsq(X, y, rcond=None)
        return X @ c - y

    start = start or {}
    if "T" in start:
        given = start["T"]
        T0 = [float(x) for x in (given if isinstance(given, (list, tuple)) else [given])]
        if len(T0) != order or not all(x > 0 for x in T0):
            raise IdentificationError(f"starting T needs {order} time constant(s) > 0 s, one per pole")
        candidates = [np.log(T0)]
    else:
        grid = np.log(np.geomspace(2 * h, span / 4, 8 if order <= 2 else 5))
        scored = sorted(
            (float(np.sum(residual(np.r_[combo, 0.0][: order + delay]) ** 2)), combo)
            for combo in itertools.combinations_with_replacement(grid, order)
        )
        candidates = [np.array(c) for _, c in scored[:2]]
    if delay and "L" not in start:  # a delay trades against zeros: try a few from each start
        L_grid = [x for x in (0.0, 2 * h, 5 * h, 10 * h, 20 * h) if x <= L_max]
        candidates = [min((np.r_[c, L] for L in L_grid), key=lambda p: float(np.sum(residual(p) ** 2)))
                      for c in candidates]
    else:
        L0 = min(float(start.get("L", 0.0)), L_max)
        candidates = [np.r_[c, L0][: order + delay] for c in candidates]
    lo = [lo_T] * order + ([0.0] if delay else [])
    hi = [hi_T] * order + ([L_max] if delay else [])
    best = None
    for c in candidates:
        p0 = np.clip(c, lo, hi)
        r = least_squares(residual, p0, bounds=(lo, hi), x_scale=[1.0] * order + ([h] if delay else []),
                          diff_step=1e-7, xtol=1e-10, ftol=1e-12, gtol=1e-12, max_nfev=300)
        if best is None or r.cost < best.cost:
            best = r
    assert best is not None
    T, L = unpack(best.x)
    X = _design(du, h, T, L, zeros)
    c, *_ = np.linalg.lstsq(X, y, rcond=None)
    ym = X @ c
    order_T = sorted(T)
    model = OEModel(tuple(float(x) for x in c[:-1]), tuple(order_T), L)
    return OEFit(model, float(c[-1]), float(np.mean((y - ym) ** 2)), ym)


@dataclass(frozen=True)
class MISOFit:
    """One output's elements fitted together from a record in which several inputs
    move (a MIMO experiment): a model per input, the rest value, loss, ym."""

    models: tuple[OEModel, ...]
    offset: float
    loss: float
    ym: np.ndarray = field(repr=False)


def fit_oe_miso(U: npt.ArrayLike, y: npt.ArrayLike, h: float, orders: Sequence[int], zeros: int = 0, *,
                delay: bool = True, u0: npt.ArrayLike | None = None) -> MISOFit:
    """y = sum_j G_j(s) u_j + rest, all G_j fitted at once (output error).  The
    starting values come from two rounds of backfitting (each G_j fitted alone to
    what the others leave unexplained), then one joint least-squares fit."""
    U = np.asarray(U, dtype=float)
    y = np.asarray(y, dtype=float)
    m = U.shape[1]
    rest = U[0] if u0 is None else np.asarray(u0, dtype=float)
    dU = U - rest
    parts = [np.zeros_like(y) for _ in range(m)]
    starts: list[OEModel] = []
    for _ in range(2):  # each round searches afresh: starting where the last ended can stick
        starts = []
        for j in range(m):
            others = sum(parts[k] for k in range(m) if k != j)
            fit = fit_oe(U[:, j], y - others, h, orders[j], zeros, delay=delay, u0=rest[j])
            parts[j] = fit.ym - fit.offset
            starts.append(fit.model)
    span = (y.size - 1) * h
    lo = np.concatenate([[math.log(0.05 * h)] * k + ([0.0] if delay else []) for k in orders])
    hi = np.concatenate([[math.log(5 * span)] * k + ([0.25 * span] if delay else []) for k in orders])

    def unpack(p: np.ndarray) -> list[tuple[list[float], float]]:
        out, at = [], 0
        for k in orders:
            out.append(([math.exp(x) for x in p[at:at + k]], float(p[at + k]) if delay else 0.0))
            at += k + delay
        return out

    def design(p: np.ndarray) -> np.ndarray:
        cols: list[np.ndarray] = []
        for j, (T, L) in enumerate(unpack(p)):
            cols += _columns(dU[:, j], h, T, L, zeros)
        return np.column_stack(cols + [np.ones_like(y)])

    def residual(p: np.ndarray) -> np.ndarray:
        X = design(p)
        c, *_ = np.linalg.lstsq(X, y, rcond=None)
        return X @ c - y

    p0 = np.concatenate([np.r_[np.log(g.T), [g.L] if delay else []] for g in starts])
    r = least_squares(residual, np.clip(p0, lo, hi), bounds=(lo, hi),
                      x_scale=np.concatenate([[1.0] * k + ([h] if delay else []) for k in orders]),
                      diff_step=1e-7, xtol=1e-10, ftol=1e-12, gtol=1e-12, max_nfev=300)
    X = design(r.x)
    c, *_ = np.linalg.lstsq(X, y, rcond=None)
    ym = X @ c
    models, at = [], 0
    for T, L in unpack(r.x):
        models.append(OEModel(tuple(float(x) for x in c[at:at + zeros + 1]), tuple(sorted(T)), L))
        at += zeros + 1
    return MISOFit(tuple(models), float(c[-1]), float(np.mean((y - ym) ** 2)), ym)


def simulate_oe(model: OEModel, u: npt.ArrayLike, h: float, u0: float, offset: float) -> np.ndarray:
    """The model output for input u about the rest values (u0, offset)."""
    du = np.asarray(u, dtype=float) - u0
    return offset + simulate(np.array(model.num), np.array(model.den), h, du, model.L)
