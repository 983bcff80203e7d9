"""The identified model as a system: a transfer matrix of DelayTF elements (outputs x
inputs) with its state-space form, static gains, poles, transmission zeros and phase,
and a side-by-side comparison with the physical linearization.

Elements fitted one by one (SIMO experiments) carry the pole of a lower tank twice,
in each element of its output (tank 1's time constant in G11 and in G12), identified
with slightly different values; det G(s) would then have a zero next to each such
pair that the process does not have.  So poles of one output's elements within 5 %
of each other are taken as the one pole they are (their mean) before det G is formed,
and the zeros of det G that then coincide with a pole cancel with it.  A state-space
model (subspace fit) needs none of this: its zeros are those of (A, B, C).
Dead times are left out of the state-space form (they add no finite zeros).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy import linalg, signal

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.plants.linear import finite_zeros, zero_limit

#: Poles of one output's elements closer than this (relative) are one pole.
MERGE_TOL = 0.05
#: After merging, a zero of det G this close to a pole (relative) cancels with it.
CANCEL_TOL = 1e-6


@dataclass(frozen=True)
class SystemModel:
    """A continuous model; elements[o][i] is None when input i never moved.  (A, B, C)
    realize the elements (block-diagonal when built from them); `zeros` are the
    transmission zeros of a complete square model (else empty), sorted by real part."""

    elements: tuple[tuple[DelayTF | None, ...], ...]
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    zeros: tuple[complex, ...]

    @property
    def complete(self) -> bool:
        return all(e is not None for row in self.elements for e in row)

    @property
    def static_gains(self) -> np.ndarray:
        """G(0), outputs x inputs (NaN where an element is missing)."""
        return np.array([[np.nan if e is None else e.static_gain for e in row] for row in self.elements])

    @property
    def phase(self) -> str:
        """'nonminimum' with a transmission zero in the closed right half-plane."""
        return "nonminimum" if any(z.real >= 0 for z in self.zeros) else "minimum"


def _clean(z: np.ndarray) -> tuple[complex, ...]:
    out = [complex(c.real, 0.0) if abs(c.imag) < 1e-9 * max(1e-3, abs(c)) else complex(c) for c in z]
    return tuple(sorted(out, key=lambda c: (c.real, c.imag)))


def _merge_row_poles(row: Sequence[DelayTF | None]) -> list[DelayTF | None]:
    """Replace the poles of a row's elements that agree within MERGE_TOL by their
    mean, keeping each element's static gain (den(0) unchanged)."""
    roots = [list(g.poles()) if g is not None else [] for g in row]
    flat = [(k, j) for k, r in enumerate(roots) for j in range(len(r))]
    for a, (k1, j1) in enumerate(flat):
        for k2, j2 in flat[a + 1:]:
            p1, p2 = roots[k1][j1], roots[k2][j2]
            if k1 != k2 and abs(p1.imag) < 1e-12 and abs(p2.imag) < 1e-12 and p1 != 0 \
                    and abs(p1 - p2) <= MERGE_TOL * abs(p1):
                roots[k1][j1] = roots[k2][j2] = (p1 + p2) / 2
    out: list[DelayTF | None] = []
    for g, r in zip(row, roots):
        if g is None or not r:
            out.append(g)
            continue
        den = np.real(np.poly(r)) * g.den[0]
        if g.den[-1] != 0 and den[-1] != 0:
            den = den * (g.den[-1] / den[-1])
        out.append(DelayTF(g.num, tuple(den), g.delay))
    return out


def _det_zeros(rows: Sequence[Sequence[DelayTF]]) -> tuple[complex, ...]:
    """Zeros of det G for a 2x2 matrix of rational elements, less those that cancel."""
    (g11, g12), (g21, g22) = rows
    P = np.polymul
    num: np.ndarray = np.polysub(P(P(g11.num, g22.num), P(g12.den, g21.den)), P(P(g12.num, g21.num), P(g11.den, g22.den)))
    num = np.trim_zeros(num, "f")
    zeros = list(np.roots(num)) if num.size > 1 else []
    # The poles of det G's denominator, each element's own (np.roots of the product
    # would split its double roots by ~1e-8).
    poles = [p for g in (g11, g22, g12, g21) for p in g.poles()]
    limit = zero_limit(max((abs(p) for p in poles), default=0.0))
    zeros = [z for z in zeros if abs(z) < limit]  # not a root of rounding's leading coefficient
    kept = []
    for z in zeros:
        near = [k for k, p in enumerate(poles) if abs(z - p) <= max(CANCEL_TOL * abs(p), 1e-12)]
        if near:
            poles.pop(near[0])
        else:
            kept.append(z)
    return _clean(np.array(kept))


def from_elements(elements: Sequence[Sequence[DelayTF | None]]) -> SystemModel:
    """A transfer matrix fitted element by element, realized block-diagonally."""
    rows = tuple(tuple(row) for row in elements)
    p, m = len(rows), len(rows[0])
    zeros: tuple[complex, ...] = ()
    if p == m == 2 and all(g is not None for row in rows for g in row):
        merged = [_merge_row_poles(row) for row in rows]
        zeros = _det_zeros(merged)  # type: ignore[arg-type]  # no None: every element checked just above
    blocks, cols = [], []
    for o, row in enumerate(rows):
        for i, g in enumerate(row):
            if g is None or len(g.den) == 1:
                continue
            A, B, C, _ = signal.tf2ss(g.num, g.den)
            blocks.append(A)
            cols.append((o, i, B[:, 0], C[0]))
    A = linalg.block_diag(*blocks) if blocks else np.zeros((0, 0))
    B, C = np.zeros((A.shape[0], m)), np.zeros((p, A.shape[0]))
    at = 0
    for o, i, b, c in cols:
        B[at:at + b.size, i] = b
        C[o, at:at + b.size] = c
        at += b.size
    return SystemModel(rows, A, B, C, zeros)


def from_state_space(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> SystemModel:
    """Elements of a (continuous, D = 0) state-space model as SISO transfer functions,
    and the model's own transmission zeros."""
    p, m = C.shape[0], B.shape[1]
    limit = zero_limit(float(np.abs(linalg.eigvals(A)).max(initial=0.0)))
    elements = []
    for o in range(p):
        row = []
        for i in range(m):
            num, den = signal.ss2tf(A, B[:, [i]], C[[o], :], np.zeros((1, 1)))
            n = np.trim_zeros(np.where(np.abs(num[0]) <= 1e-12 * np.abs(num[0]).max(), 0.0, num[0]), "f")
            # A leading coefficient of rounding (C B of an element of relative degree
            # 2, 1e-10 or so) puts a root beyond zero_limit: it goes, with its root.
            while n.size > 1 and np.abs(np.roots(n)).max() >= limit:
                n = n[1:]
            row.append(DelayTF(tuple(n) if n.size else (0.0,), tuple(den), 0.0))
        elements.append(tuple(row))
    zeros: tuple[complex, ...] = ()
    if p == m and p >= 2:
        zeros = _clean(finite_zeros(A, B, C, np.zeros((p, m))))
    return SystemModel(tuple(elements), np.asarray(A, float), np.asarray(B, float), np.asarray(C, float), zeros)


def element_zeros(g: DelayTF) -> np.ndarray:
    """The zeros of one element (1/s), less those beyond zero_limit of its fastest
    pole: a numerator's leading coefficient that should be 0 (a state-space fit's
    C B of an element of relative degree 2) is left at rounding's 1e-10 or so, and
    its root at +-1e10, its sign by the machine's rounding."""
    z = g.zeros()
    poles = g.poles()
    return z[np.abs(z) < zero_limit(float(np.abs(poles).max(initial=0.0)))]


def time_constants(g: DelayTF) -> list[float]:
    """-1/p for the real stable poles of an element (s), largest first."""
    out = [-1.0 / p.real for p in g.poles() if abs(p.imag) < 1e-9 and p.real < 0]
    return sorted(out, reverse=True)
