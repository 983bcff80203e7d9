"""Closed-loop figures of one loop from sampled signals (the headless run's summary).

Pure numpy over arrays: time t (s), output y and reference r (normalized).  The
"step" is the last jump of the reference larger than `min_step`; overshoot and
settling time are measured from it, the final error and the IAE over the whole
window given.

Example
-------
>>> import numpy as np
>>> t = np.arange(5.0); r = np.array([0, 1, 1, 1, 1.0]); y = np.array([0, 0, 1.1, 1, 1.0])
>>> m = loop_metrics(t, y, r)
>>> round(m.overshoot, 1), m.settling_time
(10.0, 2.0)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Reference changes smaller than this (normalized) are not steps: a nudged mean
#: ramps in steps of a few thousandths per sample.
MIN_STEP = 0.01


@dataclass(frozen=True)
class LoopMetrics:
    """final_error : r - y at the last sample
    iae : integral of |r - y| dt over the window (normalized x s)
    step : size of the last reference step (None: no step in the window)
    step_time : when it happened, s
    overshoot : peak beyond the new reference, % of the step (>= 0)
    settling_time : s after the step until |r - y| stays within band x |step|
        (None: not settled by the end of the window)
    """

    final_error: float
    iae: float
    step: float | None = None
    step_time: float | None = None
    overshoot: float | None = None
    settling_time: float | None = None


def loop_metrics(t: np.ndarray, y: np.ndarray, r: np.ndarray, *, band: float = 0.02,
                 min_step: float = MIN_STEP) -> LoopMetrics:
    """Figures of one loop over the samples given (at least one)."""
    t, y, r = (np.asarray(a, dtype=float) for a in (t, y, r))
    if not (t.shape == y.shape == r.shape) or t.ndim != 1 or t.size == 0:
        raise ValueError("t, y and r must be equal-length, non-empty 1-D arrays")
    e = r - y
    dt = np.diff(t, append=t[-1] + (t[-1] - t[-2] if t.size > 1 else 0.0))
    iae = float(np.sum(np.abs(e) * dt))
    jumps = np.nonzero(np.abs(np.diff(r)) > min_step)[0]
    if jumps.size == 0:
        return LoopMetrics(float(e[-1]), iae)
    k = int(jumps[-1]) + 1
    step = float(r[k] - r[k - 1])
    after = slice(k, None)
    peak = float(np.max(np.sign(step) * (y[after] - r[after])))
    overshoot = max(0.0, peak / abs(step) * 100.0)
    outside = np.nonzero(np.abs(e[after]) > band * abs(step))[0]
    if outside.size == 0:
        settling: float | None = 0.0
    elif outside[-1] + 1 >= e[after].size:
        settling = None
    else:
        settling = float(t[k + outside[-1] + 1] - t[k])
    return LoopMetrics(float(e[-1]), iae, step, float(t[k]), overshoot, settling)


def rise_time(t: np.ndarray, y: np.ndarray, r: np.ndarray, *, low: float = 0.1, high: float = 0.9,
              min_step: float = MIN_STEP) -> float | None:
    """Rise time of the last reference step (the one loop_metrics measures), s:
    from y first covering `low` of the step to its first covering `high` of it,
    counted from y just before the step.  None without a step, or when y has not
    reached `high` by the end of the window.

    >>> t = np.arange(6.0); r = np.array([0, 1, 1, 1, 1, 1.0])
    >>> rise_time(t, np.array([0, 0, 0.2, 0.6, 0.95, 1.0]), r)
    2.0
    """
    t, y, r = (np.asarray(a, dtype=float) for a in (t, y, r))
    jumps = np.nonzero(np.abs(np.diff(r)) > min_step)[0]
    if jumps.size == 0:
        return None
    k = int(jumps[-1]) + 1
    step = float(r[k] - r[k - 1])
    covered = np.sign(step) * (y[k:] - y[k - 1]) / abs(step)
    first_low = np.nonzero(covered >= low)[0]
    first_high = np.nonzero(covered >= high)[0]
    if first_high.size == 0:
        return None
    return float(t[k + first_high[0]] - t[k + first_low[0]])
