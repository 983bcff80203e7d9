"""Design of a digital state-feedback tracking system (Desautel 3.1, 4.1; control.md).

From a linear model about an operating point (x_e, u_e)::

    Phi = e^(A T),  Gamma = int_0^T e^(A t) dt B                      (3.1.2, ZOH)
    Phi_d = [[Phi, 0], [C, I]],  Gamma_d = [[Gamma], [0]]              (3.1.5, 4.1.4)

one digital integrator per tracked output.  The closed-loop poles are the normalized
Bessel roots of Table 8 (1 s settling time) divided by the settling time Ts, optionally
after poles the user fixes (his QTP keeps two slow plant zeros), mapped by z = e^(s T).
L_d = [L1, L2] places them: ``eig(Phi_d - Gamma_d L_d)`` are the z-poles.

Placement is ``scipy.signal.place_poles`` with method "YT" (Tits and Yang).  With one
input the gain is unique (it equals Ackermann's).  With several inputs infinitely many
gains place the same poles; YT picks the one whose closed-loop eigenvectors are as
orthogonal as it can make them, a robust choice, but not Matlab's ``place``, so
Desautel's QTP L1, L2 cannot be recomputed (control.md): check the poles and delta.

Robustness (4.1.3): delta = 1 / ||G||_inf, G the loop from a perturbation w at the
plant input to the controller output v with r = 0, in discrete time (control.md: his
0.8451 comes out only so)::

    [x; x_a][k+1] = [[Phi - Gamma L1, Gamma L2], [-C, I]] [x; x_a] + [Gamma; 0] w
    v = [-L1, L2] [x; x_a]

Units are the model's (Desautel: cm, V, s).

Example (Desautel's CTP, 3.4)
-------
>>> import numpy as np
>>> m = OperatingModel(A=[[-0.055988, 0], [0.055988, -0.057025]], B=[[0.24813], [0]],
...                    C=[[0, 1]], x_e=[15.0, 14.73], u_e=[6.887])
>>> d = design(m, 0.1, settling_time=20.0)
>>> np.round(d.L, 3).tolist()
[[2.118, 9.976, 0.132]]
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from scipy import linalg, optimize, signal

from quadtank_tui.core.plants.linear import zoh
from quadtank_tui.core.controllers.statefb.bessel import BESSEL_POLES  # noqa: E402  (re-exported)

#: Placement method of scipy.signal.place_poles (see the module docstring).
PLACEMENT_METHOD = "YT"


class PlacementError(ValueError):
    """The model or the poles asked for do not give a state-feedback design."""


def _matrix(name: str, value: object, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    a = np.atleast_2d(np.array(value, dtype=float))  # a copy: it is made read-only
    if a.ndim != 2 or not np.all(np.isfinite(a)):
        raise PlacementError(f"{name} must be a finite matrix")
    if rows is not None and a.shape[0] != rows:
        raise PlacementError(f"{name} must have {rows} rows, got {a.shape[0]}")
    if cols is not None and a.shape[1] != cols:
        raise PlacementError(f"{name} must have {cols} columns, got {a.shape[1]}")
    return a


def _vector(name: str, value: object, size: int) -> np.ndarray:
    v = np.array(value, dtype=float).reshape(-1)
    if v.size != size or not np.all(np.isfinite(v)):
        raise PlacementError(f"{name} must be {size} finite numbers")
    return v


@dataclass(frozen=True)
class OperatingModel:
    """dw/dt = A w + B v, y = C x about (x_e, u_e): x = x_e + w, u = u_e + v.

    C selects the tracked outputs (one integrator each).  u_min, u_max bound the
    actuators (default 0 and +inf).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    x_e: np.ndarray
    u_e: np.ndarray
    # None (0 and +inf) is replaced by an array in __post_init__: after it the fields are arrays.
    u_min: np.ndarray = field(default=None)  # type: ignore[arg-type]  # see above
    u_max: np.ndarray = field(default=None)  # type: ignore[arg-type]  # see above

    def __post_init__(self) -> None:
        A = _matrix("A", self.A)
        n = A.shape[0]
        if A.shape != (n, n):
            raise PlacementError(f"A must be square, got {A.shape[0]}x{A.shape[1]}")
        B = _matrix("B", self.B, n)
        C = _matrix("C", self.C, None, n)
        m, p = B.shape[1], C.shape[0]
        if p > m:
            raise PlacementError(f"{p} tracked outputs need at least {p} inputs, the model has {m}")
        u_min = np.zeros(m) if self.u_min is None else _vector("u_min", self.u_min, m)
        u_max = np.full(m, np.inf) if self.u_max is None else np.array(self.u_max, dtype=float).reshape(-1)
        if u_max.size != m or np.any(np.isnan(u_max)) or np.any(u_max <= u_min):
            raise PlacementError("u_max must be above u_min for every input")
        for name, value in (("A", A), ("B", B), ("C", C), ("x_e", _vector("x_e", self.x_e, n)),
                            ("u_e", _vector("u_e", self.u_e, m)), ("u_min", u_min), ("u_max", u_max)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def m(self) -> int:
        return self.B.shape[1]

    @property
    def p(self) -> int:
        return self.C.shape[0]


def augment(Phi: np.ndarray, Gamma: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Design model (3.1.5 / 4.1.4) with Phi_a = Gamma_a = I."""
    n, m = Gamma.shape
    p = C.shape[0]
    Phi_d = np.block([[Phi, np.zeros((n, p))], [C, np.eye(p)]])
    Gamma_d = np.vstack([Gamma, np.zeros((p, m))])
    return Phi_d, Gamma_d


def bessel_poles(order: int, settling_time: float) -> np.ndarray:
    """Table 8's poles of `order` for a settling time in s (rad/s)."""
    if order not in BESSEL_POLES:
        raise PlacementError(f"Table 8 has Bessel poles of order 1..6, {order} are needed")
    if not settling_time > 0 or not math.isfinite(settling_time):
        raise PlacementError(f"the settling time must be > 0 s, got {settling_time!r}")
    return np.array(BESSEL_POLES[order]) / settling_time


def _conjugate_closed(poles: np.ndarray) -> bool:
    rest = list(poles[np.abs(poles.imag) > 1e-12])
    while rest:
        p = rest.pop()
        k = int(np.argmin([abs(q - p.conjugate()) for q in rest])) if rest else -1
        if k < 0 or abs(rest[k] - p.conjugate()) > 1e-9 * max(1.0, abs(p)):
            return False
        rest.pop(k)
    return True


@dataclass(frozen=True)
class Design:
    """One design: the discrete model, the poles and the gains L = [L1, L2]."""

    model: OperatingModel
    T: float
    Phi: np.ndarray
    Gamma: np.ndarray
    Phi_d: np.ndarray
    Gamma_d: np.ndarray
    poles_s: np.ndarray
    poles_z: np.ndarray
    L: np.ndarray
    delta: float

    @property
    def L1(self) -> np.ndarray:
        """State gain, m x n."""
        return self.L[:, : self.model.n]

    @property
    def L2(self) -> np.ndarray:
        """Integrator gain, m x p."""
        return self.L[:, self.model.n:]

    def placed_poles(self) -> np.ndarray:
        """eig(Phi_d - Gamma_d L), sorted like poles_z (a check, and for display)."""
        return _match(np.linalg.eigvals(self.Phi_d - self.Gamma_d @ self.L), self.poles_z)


def _match(found: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """`found` reordered to pair with `wanted` (greedy nearest)."""
    rest = list(found)
    out = []
    for w in wanted:
        k = int(np.argmin([abs(f - w) for f in rest]))
        out.append(rest.pop(k))
    return np.array(out)


def design(
    model: OperatingModel,
    T: float,
    *,
    settling_time: float | None = None,
    poles: Sequence[complex] = (),
    use_zeros: bool = False,
) -> Design:
    """Place the closed-loop poles of the design model at sampling time T (s).

    `poles` are s-plane poles (rad/s) the user fixes; with `use_zeros` the plant's
    slow zeros come first (:func:`slow_zeros`, Desautel 4.1.2); the rest, up to n + p,
    are Bessel poles scaled to `settling_time`.  Giving all n + p poles needs no
    settling time.  PlacementError says what is wrong (order, conjugates, controllability).
    """
    if not T > 0 or not math.isfinite(T):
        raise PlacementError(f"the sampling time must be > 0 s, got {T!r}")
    order = model.n + model.p
    chosen = [complex(s) for s in poles]
    if use_zeros:
        if settling_time is None:
            raise PlacementError("choosing the slow zeros needs a settling time")
        chosen = list(slow_zeros(model, settling_time)) + chosen
    fixed = np.array(chosen, dtype=complex)
    if fixed.size > order:
        raise PlacementError(f"{fixed.size} poles given, the design model has order {order}")
    if np.any(fixed.real >= 0):
        raise PlacementError("every pole given must have a negative real part")
    if fixed.size < order:
        if settling_time is None:
            raise PlacementError(f"{order - fixed.size} poles are not given: a settling time is needed")
        fixed = np.concatenate([fixed, bessel_poles(order - fixed.size, settling_time)])
    if not _conjugate_closed(fixed):
        raise PlacementError("complex poles must come in conjugate pairs")
    Phi, Gamma = zoh(model.A, model.B, T)
    Phi_d, Gamma_d = augment(Phi, Gamma, model.C)
    poles_z = np.exp(fixed * T)
    L = _place(Phi_d, Gamma_d, poles_z)
    placed = _match(np.linalg.eigvals(Phi_d - Gamma_d @ L), poles_z)
    if np.max(np.abs(placed - poles_z)) > 1e-6:
        raise PlacementError("the poles could not be placed (is the model controllable?)")
    return Design(model, float(T), Phi, Gamma, Phi_d, Gamma_d, fixed, poles_z, L,
                  robustness(Phi, Gamma, model.C, L[:, : model.n], L[:, model.n:]))


def transmission_zeros(model: OperatingModel) -> np.ndarray:
    """Finite zeros of (A, B, C, 0) from tracked outputs to inputs (p = m), rad/s."""
    n, m, p = model.n, model.m, model.p
    if p != m:
        return np.array([], dtype=complex)
    M = np.block([[model.A, model.B], [model.C, np.zeros((p, m))]])
    N = np.block([[np.eye(n), np.zeros((n, m))], [np.zeros((p, n + m))]])
    z = linalg.eigvals(M, N)
    return z[np.isfinite(z)]


def slow_zeros(model: OperatingModel, settling_time: float) -> tuple[complex, ...]:
    """Plant zeros to use as closed-loop poles (Vaccaro's rule, Desautel 4.1.2): the
    stable ones slower than 4 s1 / Ts (s1 = Table 8's first-order pole), and, our
    extension for a nonminimum-phase setting, the mirror image -conj(z) of a
    right-half-plane zero (placing a pole there would need huge gains)."""
    limit = 4 * BESSEL_POLES[1][0].real / settling_time
    out = []
    for z in transmission_zeros(model):
        z = complex(z.real, 0.0) if abs(z.imag) < 1e-12 else complex(z)
        if z.real > 0:
            z = -z.conjugate()
        if limit < z.real < 0:
            out.append(z)
    return tuple(sorted(out, key=lambda z: (z.real, z.imag)))


def _place(Phi_d: np.ndarray, Gamma_d: np.ndarray, poles_z: np.ndarray) -> np.ndarray:
    try:
        with warnings.catch_warnings():
            # YT's "convergence not reached" concerns its robustness criterion, not the
            # poles, which design() checks itself.
            warnings.simplefilter("ignore", UserWarning)
            result = signal.place_poles(Phi_d, Gamma_d, poles_z, method=PLACEMENT_METHOD)
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise PlacementError(f"pole placement failed: {exc}") from None
    return np.real_if_close(result.gain_matrix).real


def _freq_grid(points: int = 4000) -> np.ndarray:
    """Normalized frequencies theta = w T in (0, pi], log-spaced, Nyquist included."""
    return np.concatenate([np.logspace(-6, math.log10(math.pi), points - 1), [math.pi]])


def _response(A: np.ndarray, B: np.ndarray, Cm: np.ndarray, theta: np.ndarray | float) -> np.ndarray:
    """Cm (zI - A)^-1 B at z = e^(i theta), stacked along theta's shape."""
    z = np.exp(1j * np.asarray(theta, dtype=float))
    M = z[..., None, None] * np.eye(A.shape[0]) - A
    return Cm @ np.linalg.solve(M, np.broadcast_to(B, (*z.shape, *B.shape)))


def loop_to_perturbation(Phi: np.ndarray, Gamma: np.ndarray, C: np.ndarray,
                         L1: np.ndarray, L2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """State-space (A, B, C) of G(z), perturbation w -> controller output v, r = 0."""
    p = C.shape[0]
    A = np.block([[Phi - Gamma @ L1, Gamma @ L2], [-C, np.eye(p)]])
    B = np.vstack([Gamma, np.zeros((p, Gamma.shape[1]))])
    return A, B, np.hstack([-L1, L2])


def robustness(Phi: np.ndarray, Gamma: np.ndarray, C: np.ndarray,
               L1: np.ndarray, L2: np.ndarray) -> float:
    """delta = 1 / ||G||_inf (4.1.13), the discrete loop; 0 if the loop is unstable."""
    A, B, Cm = loop_to_perturbation(Phi, Gamma, np.atleast_2d(C), np.atleast_2d(L1), np.atleast_2d(L2))
    if np.max(np.abs(np.linalg.eigvals(A))) >= 1.0:
        return 0.0

    def gain(theta: float) -> float:
        return float(np.linalg.svd(_response(A, B, Cm, theta), compute_uv=False)[0])

    grid = _freq_grid()
    g = np.linalg.svd(_response(A, B, Cm, grid), compute_uv=False)[:, 0]
    k = int(np.argmax(g))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    best = g[k]
    if hi > lo:
        res = optimize.minimize_scalar(lambda t: -gain(t), bounds=(lo, hi), method="bounded",
                                       options={"xatol": 1e-10})
        best = max(best, -float(res.fun))
    return 1.0 / best


@dataclass(frozen=True)
class Margins:
    """Loop broken at the (single) plant input: crossover and margins.

    phase_margin in degrees at `crossover` (rad/s); gain_margin_db at `phase_crossover`
    (rad/s; the Nyquist frequency pi/T when the phase reaches -180 deg only there), or
    inf when the phase never reaches -180 deg.
    """

    phase_margin: float
    crossover: float
    gain_margin_db: float
    phase_crossover: float


def loop_margins(d: Design) -> Margins:
    """Margins of L(z) = L_d (zI - Phi_d)^-1 Gamma_d (single-input designs)."""
    if d.model.m != 1:
        raise PlacementError("loop margins are computed for single-input designs")
    grid = _freq_grid()

    def loop(theta: float) -> complex:
        return complex(_response(d.Phi_d, d.Gamma_d, d.L, theta)[0, 0])

    values = _response(d.Phi_d, d.Gamma_d, d.L, grid)[:, 0, 0]
    mag = np.abs(values)
    phase = np.unwrap(np.angle(values))
    crossings = np.nonzero((mag[:-1] - 1.0) * (mag[1:] - 1.0) <= 0)[0]
    if crossings.size == 0:
        raise PlacementError("the loop gain never crosses 1")
    i = int(crossings[0])
    wc = optimize.brentq(lambda t: abs(loop(t)) - 1.0, grid[i], grid[i + 1], xtol=1e-12)
    ph = phase[i] + math.remainder(np.angle(loop(wc)) - phase[i], 2 * math.pi)
    pm = 180.0 + math.degrees(ph)
    below = phase + math.pi  # zero where the phase is -180 deg
    at = [grid[-1]] if abs(below[-1]) < 1e-6 else []
    for j in np.nonzero(below[:-1] * below[1:] < 0)[0]:
        at.append(optimize.brentq(lambda t: float(np.interp(t, grid, below)), grid[j], grid[j + 1]))
    upper = [(-20 * math.log10(abs(loop(t))), t) for t in at if abs(loop(t)) < 1.0]
    gm, wp = min(upper) if upper else (math.inf, math.nan)
    return Margins(pm, wc / d.T, gm, wp / d.T)
