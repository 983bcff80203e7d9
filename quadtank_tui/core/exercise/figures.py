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

from quadtank_tui.core.metrics import MIN_STEP, loop_metrics

#: A pump this close to 0 or full scale is at its limit (the loop clips to [0, 1]).
LIMIT_TOL = 1e-9


def last_step_index(r: np.ndarray, min_step: float = MIN_STEP) -> int | None:
    """The first sample after the last reference jump larger than `min_step`
    (the one core.metrics.loop_metrics measures), or None without one."""
    jumps = np.nonzero(np.abs(np.diff(np.asarray(r, dtype=float))) > min_step)[0]
    return None if jumps.size == 0 else int(jumps[-1]) + 1


def iae_after(t: np.ndarray, y: np.ndarray, r: np.ndarray, k: int) -> float:
    """Integral of |r - y| dt from sample k (the step) to the end, normalized x s:
    core.metrics' IAE (each sample holds for its interval) over the samples from the step."""
    return loop_metrics(np.asarray(t, float)[k:], np.asarray(y, float)[k:], np.asarray(r, float)[k:]).iae


def coupling_peak(y_other: np.ndarray, k: int) -> float:
    """Largest |y - y at the step| of the other loop from sample k (the step) on,
    normalized: the design preview's "peak in y2" (core/design/preview.py)."""
    y = np.asarray(y_other, float)[k:]
    return float(np.max(np.abs(y - y[0]))) if y.size else 0.0


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
