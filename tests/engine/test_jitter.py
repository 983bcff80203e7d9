"""Jitter percentiles from a fixed histogram: an upper bound, at most one bin high."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quadtank_tui.engine.jitter import BINS_PER_DECADE, JitterHistogram

BIN = 10 ** (1 / BINS_PER_DECADE)  # ratio of a bin's edges (1.047)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_percentiles_bound_the_exact_ones_within_a_bin(seed: int) -> None:
    rng = np.random.default_rng(seed)
    values = np.concatenate([rng.exponential(2e-4, 20_000), rng.uniform(2e-3, 4e-2, 300)])
    values *= rng.choice([-1.0, 1.0], size=values.size)  # early and late alike
    hist = JitterHistogram()
    for v in values:
        hist.add(float(v))
    for q in (50, 90, 99, 99.9):
        exact = float(np.percentile(np.abs(values), q, method="inverted_cdf"))
        got = hist.percentile(q)
        assert exact <= got <= exact * BIN, q
    assert hist.percentile(100) == pytest.approx(np.abs(values).max())


def test_a_percentile_is_never_above_the_largest_value() -> None:
    hist = JitterHistogram()
    hist.add(0.00102)
    assert hist.percentile(99) == 0.00102


def test_empty_tiny_huge_and_nan() -> None:
    hist = JitterHistogram()
    assert hist.percentile(99) == 0.0
    hist.add(0.0)
    hist.add(1e-9)
    assert hist.percentile(99) == 1e-9
    hist.add(math.nan)
    hist.add(100.0)  # beyond 10 s: the last bin
    assert hist.n == 4 and hist.percentile(100) == 100.0


def test_the_tracked_percentiles_agree_with_a_full_count_after_every_sample() -> None:
    rng = np.random.default_rng(7)
    values = np.exp(rng.uniform(np.log(1e-7), np.log(20.0), 3000))  # all bins, in any order
    tracked, plain = JitterHistogram(), JitterHistogram(tracked=())
    for v in values:
        tracked.add(float(v))
        plain.add(float(v))
        for q in (50.0, 99.0):
            assert tracked.percentile(q) == plain.percentile(q)
