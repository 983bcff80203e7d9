"""Many parameter sets of one tank plant simulated together, for the physical fit.

A physical fit spends its time simulating: every Jacobian column is one more run of
every log, a coarse global stage is hundreds.  The plant's own step (an adaptive
Dormand-Prince to 1e-10, one level vector at a time) is the reference; this module
runs P parameter sets side by side as numpy arrays (P x tanks) with a fixed-step
classical Runge-Kutta (RK4) of at most :data:`MAX_SUBSTEP` s, the levels projected
onto [0, brim] after each sub-step as the plant does.  The fit searches with it and
reports its figures from the plant's own simulator (core.identify.physical), so the
two are compared on every fit; tests/identify hold them together.

Every tank plant is written here in one form: tank i has a cross-section area_i
(level rate = flow / area), an outlet q_i = coef_i sqrt(2 g h_i) + lam_i h_i (the
Torricelli term blended to 0 over the last :data:`FILM` cm as the plants do, plus a
laminar term) that runs into tank dst_i or out of the process, pump inflows that are
linear in the voltage above a dead zone, and a brim: a full tank's excess falls in
the fraction spill_i into the tank below it, the rest leaves.  The sensors read
kc_i h_i + offset_i, clipped at their range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

#: Longest RK4 sub-step, s (the fastest tanks of the presets have time constants of
#: 20 s and more: a 5 s step errs by about (5/20)^5/120 of a sample's change).
MAX_SUBSTEP = 5.0
#: Head below which the Torricelli term is blended to 0, in the plant's length unit
#: per cm (core.plant.H_FILM = 0.005 cm).
FILM = 0.005

Values = Mapping[str, np.ndarray]


@dataclass(frozen=True)
class Layout:
    """A plant kind in the one form above: which values play which role."""

    n: int
    #: inflow(u (P x pumps), values) -> (P x n) flows into each tank
    inflow: Callable[[np.ndarray, Values], np.ndarray]
    coef: Callable[[Values], np.ndarray]
    lam: Callable[[Values], np.ndarray]
    area: Callable[[Values], np.ndarray]
    gain: Callable[[Values], np.ndarray]
    offset: Callable[[Values], np.ndarray]
    ysat: Callable[[Values], np.ndarray]
    spill: Callable[[Values], np.ndarray]
    #: outlet i runs into tank src_dst[i] (-1: out of the process)
    dst: tuple[int, ...]
    #: a full tank i spills into tank spill_dst[i] (-1: nowhere, it is a lower tank)
    spill_dst: tuple[int, ...]
    vmax: Callable[[Values], np.ndarray]
    film: float


def _v(values: Values, name: str, like: np.ndarray) -> np.ndarray:
    return np.asarray(values[name], dtype=float) if name in values else np.zeros_like(like)


def _stack(values: Values, names: Sequence[str], default: float = 0.0) -> np.ndarray:
    ref = next(iter(values.values()))
    return np.column_stack([np.asarray(values[n], float) if n in values else np.full_like(ref, default)
                            for n in names])


def _dead(u: np.ndarray, vmin: np.ndarray) -> np.ndarray:
    return np.maximum(u - vmin, 0.0)


def _quad_inflow(u: np.ndarray, v: Values) -> np.ndarray:
    v1 = _dead(u[:, 0], _v(v, "vmin1", u[:, 0])) * v["k1"]
    v2 = _dead(u[:, 1], _v(v, "vmin2", u[:, 1])) * v["k2"]
    g1, g2 = v["gamma1"], v["gamma2"]
    return np.column_stack([g1 * v1, g2 * v2, (1 - g2) * v2, (1 - g1) * v1])


def _desautel_inflow(u: np.ndarray, v: Values) -> np.ndarray:
    v1 = _dead(u[:, 0], _v(v, "vmin1", u[:, 0]))
    v2 = _dead(u[:, 1], _v(v, "vmin2", u[:, 1]))
    return np.column_stack([v["beta1"] * v1, v["beta2"] * v2, v["beta3"] * v2, v["beta4"] * v1])


def _cascade_inflow(u: np.ndarray, v: Values) -> np.ndarray:
    q = v["beta1"] * _dead(u[:, 0], _v(v, "vmin", u[:, 0]))
    return np.column_stack([q, np.zeros_like(q)])


FOUR = ("1", "2", "3", "4")
LAYOUTS: dict[str, Layout] = {
    "quadtank": Layout(
        4, _quad_inflow,
        coef=lambda v: _stack(v, [f"a{i}" for i in FOUR]),
        lam=lambda v: _stack(v, [f"lam{i}" for i in FOUR]),
        area=lambda v: _stack(v, [f"A{i}" for i in FOUR]),
        gain=lambda v: _stack(v, ["kc"] * 4),
        offset=lambda v: _stack(v, [f"off{i}" for i in FOUR]),
        ysat=lambda v: _stack(v, [f"ysat{i}" for i in FOUR]),
        spill=lambda v: _stack(v, ["_none", "_none", "spill3", "spill4"]),
        dst=(-1, -1, 0, 1), spill_dst=(-1, -1, 0, 1),
        vmax=lambda v: np.full_like(v["kc"], 10.0), film=FILM),
    "desautel-qtp": Layout(
        4, _desautel_inflow,
        coef=lambda v: _stack(v, [f"alpha{i}" for i in FOUR]),
        lam=lambda v: _stack(v, [f"lam{i}" for i in FOUR]),
        area=lambda v: _stack(v, ["_one"] * 4, 1.0),
        gain=lambda v: _stack(v, ["kc"] * 4),
        offset=lambda v: _stack(v, [f"off{i}" for i in FOUR]),
        ysat=lambda v: _stack(v, [f"ysat{i}" for i in FOUR]),
        spill=lambda v: _stack(v, ["_none", "_none", "spill3", "spill4"]),
        dst=(-1, -1, 0, 1), spill_dst=(-1, -1, 0, 1),
        vmax=lambda v: np.asarray(v["vmax"], float), film=FILM),
    "coupled-cascade": Layout(
        2, _cascade_inflow,
        coef=lambda v: _stack(v, ["alpha1", "alpha2"]),
        lam=lambda v: _stack(v, ["lam1", "lam2"]),
        area=lambda v: np.column_stack([np.where(_v(v, "area1", v["kc1"]) > 0, _v(v, "area1", v["kc1"]), 1.0),
                                        np.ones_like(v["kc1"])]),
        gain=lambda v: _stack(v, ["kc1", "kc2"]),
        offset=lambda v: _stack(v, ["off1", "off2"]),
        ysat=lambda v: _stack(v, ["ysat1", "ysat2"]),
        spill=lambda v: _stack(v, ["spill1", "_none"]),
        dst=(1, -1), spill_dst=(1, -1),
        vmax=lambda v: np.asarray(v["vmax"], float), film=FILM),
}


def supports(kind: str) -> bool:
    """Whether plants of `kind` have a batch form here (else the fit steps the plant)."""
    return kind in LAYOUTS


@dataclass(frozen=True)
class Batch:
    """P parameter sets of one kind, as the arrays the step uses."""

    layout: Layout
    values: dict[str, np.ndarray]
    coef: np.ndarray
    lam: np.ndarray
    area: np.ndarray
    gain: np.ndarray
    offset: np.ndarray
    ysat: np.ndarray
    spill: np.ndarray
    hmax: np.ndarray
    g: np.ndarray
    vmax: np.ndarray
    #: coef sqrt(2 g), 1 / area, and the routing of the outlets (n x n: q @ route
    #: is what each tank receives from the others)
    c: np.ndarray
    inv_area: np.ndarray
    route: np.ndarray
    spill_route: np.ndarray

    @property
    def size(self) -> int:
        return int(self.coef.shape[0])


def batch(kind: str, values: Mapping[str, Sequence[float] | np.ndarray | float], size: int) -> Batch:
    """`size` parameter sets of `kind`: each value a scalar (shared) or `size` numbers."""
    lay = LAYOUTS[kind]
    v = {k: np.broadcast_to(np.asarray(x, dtype=float), (size,)).copy() for k, x in values.items()}
    route = np.zeros((lay.n, lay.n))
    spill_route = np.zeros((lay.n, lay.n))
    for i, d in enumerate(lay.dst):
        if d >= 0:
            route[i, d] = 1.0
    for i, d in enumerate(lay.spill_dst):
        if d >= 0:
            spill_route[i, d] = 1.0
    coef, area, g = lay.coef(v), lay.area(v), v["g"][:, None]
    return Batch(lay, v, coef, lay.lam(v), area, lay.gain(v), lay.offset(v), lay.ysat(v),
                 lay.spill(v), v["hmax"][:, None], g, lay.vmax(v), coef * np.sqrt(2.0 * g), 1.0 / area,
                 route, spill_route)


def rhs(b: Batch, x: np.ndarray, fin: np.ndarray) -> np.ndarray:
    """Level rates (P x n) at levels x (within [0, brim]) with the inflows fin."""
    film = b.layout.film
    if (x < film).any():
        torr = np.where(x >= film, np.sqrt(np.maximum(x, film)),
                        (np.maximum(x, 0.0) / math.sqrt(film)) * (1.5 - 0.5 * np.maximum(x, 0.0) / film))
    else:
        torr = np.sqrt(x)
    q = b.c * torr + b.lam * x
    f = fin - q + q @ b.route
    if (x >= b.hmax).any():
        over = np.where((x >= b.hmax) & (f > 0.0), f, 0.0)
        f = f - over + (b.spill * over) @ b.spill_route
    return f * b.inv_area


def substeps(h: float, rows: int, steps: int = 1024) -> int:
    """RK4 sub-steps per sample: at most :data:`MAX_SUBSTEP` s each, and more for a
    short log (about `steps` in all, so a short log is simulated nearly exactly)."""
    return max(1, math.ceil(h / MAX_SUBSTEP - 1e-9), min(8, steps // max(rows, 1)))


def simulate(b: Batch, x0: np.ndarray, u: np.ndarray, h: float, n_sub: int | None = None) -> np.ndarray:
    """Levels (rows x P x n) of every set: x[0] = x0 (P x n), then u (rows x pumps,
    or rows x P x pumps) held over each sample of h s (`n_sub` RK4 steps each,
    default :func:`substeps`)."""
    rows = u.shape[0]
    n_sub = n_sub or substeps(h, rows)
    dt = h / n_sub
    half, sixth = 0.5 * dt, dt / 6.0
    x = np.clip(np.asarray(x0, float), 0.0, b.hmax)
    out = np.empty((rows, b.size, b.layout.n))
    out[0] = x
    uu = u if u.ndim == 3 else np.broadcast_to(u[:, None, :], (rows, b.size, u.shape[1]))
    uu = np.clip(uu, 0.0, b.vmax[None, :, None])
    hmax = b.hmax
    inflow, values = b.layout.inflow, b.values
    last = None
    fin = inflow(uu[0], values)
    for k in range(1, rows):
        if last is None or not np.array_equal(uu[k - 1], last):
            last = uu[k - 1]
            fin = inflow(last, values)
        for _ in range(n_sub):
            k1 = rhs(b, x, fin)
            k2 = rhs(b, np.clip(x + half * k1, 0.0, hmax), fin)
            k3 = rhs(b, np.clip(x + half * k2, 0.0, hmax), fin)
            k4 = rhs(b, np.clip(x + dt * k3, 0.0, hmax), fin)
            x = np.clip(x + sixth * (k1 + 2.0 * k2 + 2.0 * k3 + k4), 0.0, hmax)
        out[k] = x
    return out


def sensors(b: Batch, x: np.ndarray) -> np.ndarray:
    """Sensor voltages of levels x (... x P x n): kc h + offset, clipped at the range."""
    y = b.gain * x + b.offset
    return np.where(b.ysat > 0.0, np.minimum(y, np.where(b.ysat > 0.0, b.ysat, np.inf)), y)


def steady(b: Batch, u: np.ndarray) -> np.ndarray:
    """The levels (P x n) the sets settle at with u held (pumps,), brims ignored:
    each outlet passes what flows in (q = c sqrt(2 g h) + lam h solved for h)."""
    u2 = np.clip(np.broadcast_to(np.asarray(u, float), (b.size, len(u))), 0.0, b.vmax[:, None])
    fin = b.layout.inflow(u2, b.values)
    n = b.layout.n
    x = np.zeros((b.size, n))
    into = fin.copy()
    order = _upstream_first(b.layout)
    r2g = np.sqrt(2.0 * b.g[:, 0])
    for i in order:
        q = into[:, i]
        c, lam = b.coef[:, i] * r2g, b.lam[:, i]
        # lam s^2 + c s - q = 0, s = sqrt(h)
        disc = np.sqrt(c * c + 4.0 * lam * np.maximum(q, 0.0))
        s = np.where(lam > 0, (disc - c) / np.where(lam > 0, 2.0 * lam, 1.0), np.maximum(q, 0.0) / c)
        x[:, i] = np.minimum(s * s, b.hmax[:, 0])
        d = b.layout.dst[i]
        if d >= 0:
            into[:, d] += c * np.sqrt(x[:, i]) + lam * x[:, i]
    return x


def _upstream_first(lay: Layout) -> list[int]:
    """Tanks ordered so that each comes after every tank that drains into it."""
    order: list[int] = []
    left = list(range(lay.n))
    while left:
        for i in list(left):
            if all(lay.dst[j] != i or j in order for j in range(lay.n)):
                order.append(i)
                left.remove(i)
    return order
