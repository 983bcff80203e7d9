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

from quadtank_tui.core.plant import _A, _B, _E, PlantError

Rhs = Callable[[Sequence[float]], Sequence[float]]

#: Smallest sub-step, s: accepted whatever its error, so no input loops forever.
MIN_STEP = 1e-9


def _clip(y: Sequence[float], lo: Sequence[float], hi: Sequence[float]) -> list[float]:
    return [lo[i] if y[i] < lo[i] else (hi[i] if y[i] > hi[i] else y[i]) for i in range(len(y))]


def dopri_advance(f: Rhs, x: Sequence[float], dt: float, lo: Sequence[float], hi: Sequence[float],
                  *, rtol: float, atol: float) -> tuple[float, ...]:
    """x(dt) of dx/dt = f(x), integrated to (rtol, atol) and kept in [lo, hi]."""
    if dt < 0 or not math.isfinite(dt):
        raise PlantError(f"step length must be a finite number >= 0 s, got {dt}")
    y = _clip([float(v) for v in x], lo, hi)
    if dt == 0.0:
        return tuple(y)
    n = len(y)
    r = range(n)
    t = 0.0
    step = min(dt, 1.0)
    k = [list(f(y))]
    while t < dt:
        last = t + step >= dt
        if last:
            step = dt - t
        ks = k[:1]
        for s in range(1, 7):
            a = _A[s]
            ks.append(list(f([y[i] + step * sum(a[j] * ks[j][i] for j in range(s)) for i in r])))
        y_new = [y[i] + step * sum(_B[j] * ks[j][i] for j in range(7)) for i in r]
        err = 0.0
        for i in r:
            e = step * sum(_E[j] * ks[j][i] for j in range(7))
            err = max(err, abs(e) / (atol + rtol * max(abs(y[i]), abs(y_new[i]))))
        if err <= 1.0 or step <= MIN_STEP:
            t = dt if last else t + step
            y = _clip(y_new, lo, hi)
            k = [list(f(y))]
            factor = 5.0 if err == 0.0 else min(5.0, max(0.2, 0.9 * err ** -0.2))
        else:
            factor = max(0.1, 0.9 * err ** -0.2)
        step = max(step * factor, MIN_STEP)
    return tuple(y)
