"""The figures of a closed-loop step that an exercise's requirements name.

Signals are normalized (1.0 = 10 V of sensor, a pump's full scale), time in s.
Every step figure is measured from the last step of the stepped loop's
reference (core.metrics: the one definition of overshoot, settling and rise
time the summary, `log compare` and the design preview use).

>>> import numpy as np
>>> t = np.arange(6.0)
>>> time_at_pump_limit(np.array([0.2, 1.0, 1.0, 0.5, 0.0, 0.3]), np.full(6, 0.3), 1.0)
3.0
"""

from __future__ import annotations

import numpy as np

from quadtank_tui.core.metrics import MIN_STEP

#: A pump this close to 0 or full scale is at its limit (the loop clips to [0, 1]).
LIMIT_TOL = 1e-9


def last_step_index(r: np.ndarray, min_step: float = MIN_STEP) -> int | None:
    """The first sample after the last reference jump larger than `min_step`
    (the one core.metrics.loop_metrics measures), or None without one."""
    jumps = np.nonzero(np.abs(np.diff(np.asarray(r, dtype=float))) > min_step)[0]
    return None if jumps.size == 0 else int(jumps[-1]) + 1


def iae_after(t: np.ndarray, y: np.ndarray, r: np.ndarray, k: int) -> float:
    """Integral of |r - y| dt from sample k (the step) to the end, normalized x s;
    each sample holds for its interval (the last one for the one before it)."""
    t, e = np.asarray(t, float)[k:], np.abs(np.asarray(r, float) - np.asarray(y, float))[k:]
    if t.size == 0:
        return 0.0
    dt = np.diff(t, append=t[-1] + (t[-1] - t[-2] if t.size > 1 else 0.0))
    return float(np.sum(e * dt))


def coupling_peak(y_other: np.ndarray, r_other: np.ndarray, k: int) -> float:
    """Largest |r - y| of the other loop from sample k (the step) on, normalized."""
    e = np.abs(np.asarray(r_other, float)[k:] - np.asarray(y_other, float)[k:])
    return float(e.max()) if e.size else 0.0


def time_at_pump_limit(u1: np.ndarray, u2: np.ndarray, h: float) -> float:
    """Seconds during which either pump was at 0 or at full scale (each sample h s)."""
    u = np.column_stack([np.asarray(u1, float), np.asarray(u2, float)])
    at = np.any((u <= LIMIT_TOL) | (u >= 1.0 - LIMIT_TOL), axis=1)
    return float(at.sum()) * h


def relative_error(value: float, physical: float) -> float:
    """|value - physical| / |physical| (a fraction); inf when the physical one is 0."""
    if physical == 0.0:
        return 0.0 if value == 0.0 else float("inf")
    return abs(value - physical) / abs(physical)
