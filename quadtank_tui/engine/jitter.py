"""Percentiles of |jitter| over a whole run, in fixed memory.

The maximum alone says little (one late sample when the machine swapped); a lab
wants to know the p99 too, and an 8-hour run cannot keep every sample's jitter.
A histogram with logarithmic bins from 1 µs to 10 s (50 per decade, so a bin is
4.7 % wide) holds any run in 352 counters; a percentile is reported as the upper
edge of its bin, so it is never smaller than the true value and at most 4.7 % above (nor above the
largest value seen).

:class:`LoopTiming` is a loop's record of its driver's measurements (samples,
overruns, the last and largest jitter, and this histogram), the LoopStats of a
snapshot when one is built.
"""

from __future__ import annotations

import bisect
import itertools
import math

import numpy as np

from quadtank_tui.engine.snapshot import LoopStats

BINS_PER_DECADE = 50
LOWEST = 1e-6     # s; |jitter| below this counts in bin 0
DECADES = 7       # up to 10 s; beyond that in the last bin
_NBINS = BINS_PER_DECADE * DECADES + 2
#: Upper edge of each bin, s (bin 0: below LOWEST; the last: everything above 10 s).
EDGES = np.concatenate(([LOWEST], LOWEST * 10.0 ** (np.arange(1, _NBINS - 1) / BINS_PER_DECADE), [math.inf]))


class JitterHistogram:
    """Counts of |jitter| per bin, and the bins holding the tracked percentiles.

    A caller that asks for a percentile after every sample tracks it: its pointer
    to its bin moves by a step or two at each add (a few times cheaper in pure
    Python than a cumulative sum).  The loop asks only when a snapshot
    is built, so it tracks none and its add is a count."""

    def __init__(self, tracked: tuple[float, ...] = (50.0, 99.0)) -> None:
        self.counts = [0] * _NBINS
        self.n = 0
        self.max = 0.0
        #: percentile -> [bin, number of samples in the bins below it]
        self._at = {q: [0, 0] for q in tracked}

    def add(self, jitter: float) -> None:
        a = abs(jitter)
        if not a >= LOWEST:  # also NaN
            b = 0
        else:
            b = min(_NBINS - 1, 1 + int(math.log10(a / LOWEST) * BINS_PER_DECADE))
        counts = self.counts
        counts[b] += 1
        self.n += 1
        if a > self.max:
            self.max = a
        for q, at in self._at.items():
            i, below = at
            if b < i:
                below += 1
            rank = max(1, math.ceil(q / 100.0 * self.n))
            while below >= rank:            # the rank fell into a lower bin
                i -= 1
                below -= counts[i]
            while below + counts[i] < rank:  # or a higher one
                below += counts[i]
                i += 1
            at[0], at[1] = i, below

    def percentile(self, q: float) -> float:
        """Upper bound of the q-th percentile of |jitter| (its bin's edge, or the
        largest value seen if that is smaller), s; 0 if empty."""
        if self.n == 0:
            return 0.0
        at = self._at.get(q)
        if at is not None:
            i = at[0]
        else:
            rank = max(1, math.ceil(q / 100.0 * self.n))
            i = bisect.bisect_left(list(itertools.accumulate(self.counts)), rank)  # numpy's cumsum of a list: 2x slower
        return min(float(EDGES[i]), self.max)


class LoopTiming:
    """A loop's timing as the driver measures it, counted as it comes (a few additions a sample);
    :meth:`stats` makes the frozen LoopStats a snapshot carries, when one is built."""

    def __init__(self) -> None:
        self.samples = self.overruns = self.skipped = 0
        self.jitter_last = self.jitter_max = self.last_wall = 0.0
        # No tracked percentiles: they are read a snapshot at a time, not every sample,
        # and a full count then is cheaper than moving pointers at each add.
        self.histogram = JitterHistogram(tracked=())

    def add(self, jitter: float, missed: int, wall: float) -> None:
        self.samples += 1
        if missed:
            self.overruns += 1
            self.skipped += missed
        self.jitter_last, self.last_wall = jitter, wall
        a = abs(jitter)
        if a > self.jitter_max:
            self.jitter_max = a
        self.histogram.add(jitter)

    def stats(self) -> LoopStats:
        h = self.histogram
        return LoopStats(samples=self.samples, overruns=self.overruns, skipped=self.skipped,
                         jitter_last=self.jitter_last, jitter_max=self.jitter_max,
                         jitter_p50=h.percentile(50), jitter_p99=h.percentile(99),
                         last_sample_wall=self.last_wall)
