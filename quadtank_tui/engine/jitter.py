"""Percentiles of |jitter| over a whole run, in fixed memory.

The maximum alone says little (one late sample when the machine swapped); a lab
wants to know the p99 too, and an 8-hour run cannot keep every sample's jitter.
A histogram with logarithmic bins from 1 µs to 10 s (50 per decade, so a bin is
4.7 % wide) holds any run in 352 counters; a percentile is reported as the upper
edge of its bin, so it is never smaller than the true value and at most 4.7 % above (nor above the
largest value seen).
"""

from __future__ import annotations

import math

import numpy as np

BINS_PER_DECADE = 50
LOWEST = 1e-6     # s; |jitter| below this counts in bin 0
DECADES = 7       # up to 10 s; beyond that in the last bin
_NBINS = BINS_PER_DECADE * DECADES + 2
#: Upper edge of each bin, s (bin 0: below LOWEST; the last: everything above 10 s).
EDGES = np.concatenate(([LOWEST], LOWEST * 10.0 ** (np.arange(1, _NBINS - 1) / BINS_PER_DECADE), [math.inf]))


class JitterHistogram:
    def __init__(self) -> None:
        self.counts = np.zeros(_NBINS, dtype=np.int64)
        self.n = 0
        self.max = 0.0

    def add(self, jitter: float) -> None:
        a = abs(jitter)
        if not a >= LOWEST:  # also NaN
            i = 0
        else:
            i = min(_NBINS - 1, 1 + int(math.log10(a / LOWEST) * BINS_PER_DECADE))
        self.counts[i] += 1
        self.n += 1
        if a > self.max:
            self.max = a

    def percentile(self, q: float) -> float:
        """Upper bound of the q-th percentile of |jitter| (its bin's edge, or the
        largest value seen if that is smaller), s; 0 if empty."""
        if self.n == 0:
            return 0.0
        rank = max(1, math.ceil(q / 100.0 * self.n))
        i = int(np.searchsorted(np.cumsum(self.counts), rank))
        return min(float(EDGES[i]), self.max)
