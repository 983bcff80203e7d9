"""The vectorized batch path runs the engine's experiment: same numbers, N at once."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from quadtank_tui.core.batch import pi_batch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from benchmarks.experiment import H0, PI, PLANT, U0, references, run_engine  # noqa: E402


def test_batch_matches_the_engine_sample_by_sample() -> None:
    runs = [run_engine(seed, samples=600) for seed in (1, 2, 3)]
    refs = np.stack([references(h) for h in runs])
    assert not np.array_equal(refs[0], refs[1])  # the seeds give different PRBS
    batch = pi_batch(PLANT, H0, U0, refs, PI, 1.0)
    for i, hist in enumerate(runs):
        y = np.stack([hist[f"y{j}"] for j in (1, 2, 3, 4)], axis=1)
        u = np.stack([hist["u1"], hist["u2"]], axis=1)
        assert np.max(np.abs(batch.y[i] - y)) < 1e-7
        assert np.max(np.abs(batch.u[i] - u)) < 1e-6
    assert np.ptp(batch.u[0, :, 0]) > 0.05  # the loop really moved
