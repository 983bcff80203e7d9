"""One zero-order-hold step of any tank plant: adaptive Dormand-Prince 5(4).

The same method, tableau, step control and projection as core.plant.advance (which
stays the quadruple tank's own, bit for bit), for a state of any size: the levels
are projected onto [lo, hi] after each accepted sub-step (a full tank spills, an
empty one stays empty) and the step shrinks where a flow law bends until the local
error meets the tolerance.
"""

from __future__ import annotations

import math
from typing import Callable, Sequence

# The tableau's coefficients by name (core.plant's, where its own step uses them): the
# stage sums below are written out term by term, the same operations in the same order
# as sum(a[j] * k[j][i] for j), so the numbers are bit for bit those of the loop form at
# about half its cost (a fit of the physical constants runs thousands of these per
# iteration).
from quadtank_tui.core.plant import (
    _A21, _A31, _A32, _A41, _A42, _A43, _A51, _A52, _A53, _A54, _A61, _A62, _A63, _A64, _A65,
    _A71, _A72, _A73, _A74, _A75, _A76, _B1, _B2, _B3, _B4, _B5, _B6, _B7,
    _E1, _E2, _E3, _E4, _E5, _E6, _E7, PlantError,
)

Rhs = Callable[[Sequence[float]], Sequence[float]]

#: Smallest sub-step, s: accepted whatever its error, so no input loops forever.
MIN_STEP = 1e-9


def _clip(y: Sequence[float], lo: Sequence[float], hi: Sequence[float]) -> list[float]:
    return [lo[i] if y[i] < lo[i] else (hi[i] if y[i] > hi[i] else y[i]) for i in range(len(y))]


def _step(f: Rhs, y: list[float], k0: Sequence[float], step: float, rtol: float, atol: float
          ) -> tuple[list[float], float]:
    """One Dormand-Prince step of `step` s from y: the 5th-order solution and its
    error estimate scaled by the tolerance (<= 1: accepted)."""
    r = range(len(y))
    k1 = f([y[i] + step * (_A21 * k0[i]) for i in r])
    k2 = f([y[i] + step * (_A31 * k0[i] + _A32 * k1[i]) for i in r])
    k3 = f([y[i] + step * (_A41 * k0[i] + _A42 * k1[i] + _A43 * k2[i]) for i in r])
    k4 = f([y[i] + step * (_A51 * k0[i] + _A52 * k1[i] + _A53 * k2[i] + _A54 * k3[i]) for i in r])
    k5 = f([y[i] + step * (_A61 * k0[i] + _A62 * k1[i] + _A63 * k2[i] + _A64 * k3[i] + _A65 * k4[i])
            for i in r])
    k6 = f([y[i] + step * (_A71 * k0[i] + _A72 * k1[i] + _A73 * k2[i] + _A74 * k3[i] + _A75 * k4[i]
                           + _A76 * k5[i]) for i in r])
    y_new = [y[i] + step * (_B1 * k0[i] + _B2 * k1[i] + _B3 * k2[i] + _B4 * k3[i] + _B5 * k4[i]
                            + _B6 * k5[i] + _B7 * k6[i]) for i in r]
    err = 0.0
    for i in r:
        e = step * (_E1 * k0[i] + _E2 * k1[i] + _E3 * k2[i] + _E4 * k3[i] + _E5 * k4[i]
                    + _E6 * k5[i] + _E7 * k6[i])
        err = max(err, abs(e) / (atol + rtol * max(abs(y[i]), abs(y_new[i]))))
    return y_new, err


def dopri_advance(f: Rhs, x: Sequence[float], dt: float, lo: Sequence[float], hi: Sequence[float],
                  *, rtol: float, atol: float) -> tuple[float, ...]:
    """x(dt) of dx/dt = f(x), integrated to (rtol, atol) and kept in [lo, hi]."""
    if dt < 0 or not math.isfinite(dt):
        raise PlantError(f"step length must be a finite number >= 0 s, got {dt}")
    y = _clip([float(v) for v in x], lo, hi)
    if dt == 0.0:
        return tuple(y)
    t = 0.0
    step = min(dt, 1.0)
    k = [list(f(y))]
    while t < dt:
        last = t + step >= dt
        if last:
            step = dt - t
        y_new, err = _step(f, y, k[0], step, rtol, atol)
        if err <= 1.0 or step <= MIN_STEP:
            t = dt if last else t + step
            y = _clip(y_new, lo, hi)
            k = [list(f(y))]
            factor = 5.0 if err == 0.0 else min(5.0, max(0.2, 0.9 * err ** -0.2))
        else:
            factor = max(0.1, 0.9 * err ** -0.2)
        step = max(step * factor, MIN_STEP)
    return tuple(y)
