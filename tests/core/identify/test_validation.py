"""Validation figures on cases with a known answer."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from quadtank_tui.core.identify import IdentificationError
from quadtank_tui.core.identify.validation import (
    Z99, autocorrelation, coherence, cross_correlation, fit_percent, spectral_estimate, split_index,
)


def test_fit_percent_known_values() -> None:
    y = np.array([1.0, 2.0, 3.0, 4.0])
    assert fit_percent(y, y) == 100.0
    assert fit_percent(y, np.full(4, 2.5)) == pytest.approx(0.0)
    # |y - ym| = 0.5 * |y - mean|: 50 %
    assert fit_percent(y, y - 0.5 * (y - 2.5)) == pytest.approx(50.0)


def test_split() -> None:
    assert split_index(3600) == 1800
    assert split_index(3600, 0.75) == 2700
    assert split_index(3600, 1.0) == 0  # validate on everything
    with pytest.raises(IdentificationError):
        split_index(3600, 0.0)
    with pytest.raises(IdentificationError, match="too few rows"):
        split_index(12, 0.5)


def test_white_noise_stays_inside_the_99_percent_band() -> None:
    e = np.random.default_rng(0).normal(size=5000)
    r = autocorrelation(e)
    assert r.band == pytest.approx(Z99 / np.sqrt(5000))
    assert r.value[0] == pytest.approx(1.0)
    assert r.inside >= 0.96  # 25 lags at 1 % each: at most one or two outside


def test_coloured_residuals_and_a_missed_input_are_caught() -> None:
    rng = np.random.default_rng(1)
    e = signal.lfilter([1.0], [1.0, -0.8], rng.normal(size=5000))  # AR(1): r(k) = 0.8^k
    r = autocorrelation(e)
    assert r.value[1] == pytest.approx(0.8, abs=0.03)
    assert r.inside < 0.6
    u = rng.normal(size=5000)
    missed = 0.5 * np.r_[0.0, 0.0, 0.0, u[:-3]] + rng.normal(size=5000)  # residual still holds u(t-3)
    c = cross_correlation(u, missed)
    k = int(np.argmax(np.abs(c.value)))
    assert c.lags[k] == 3
    assert c.value[k] == pytest.approx(0.5 / np.sqrt(1.25), abs=0.03)
    assert cross_correlation(u, rng.normal(size=5000)).inside >= 0.95


def test_coherence_one_for_a_linear_noiseless_relation_and_low_for_noise() -> None:
    rng = np.random.default_rng(2)
    u = rng.normal(size=3600)
    y = signal.lfilter([0.0, 0.1], [1.0, -0.9], u)
    f, c = coherence(u, y, 1.0)
    assert f[-1] == pytest.approx(0.5) and len(f) == 361  # Hamming window of 720 points
    assert c[1:].min() > 0.99  # windowing leaves a small bias (and the mean is removed at 0 Hz)
    _, c2 = coherence(u, rng.normal(size=3600), 1.0)
    assert c2.mean() < 0.35


def test_spectral_estimate_matches_the_true_frequency_response() -> None:
    rng = np.random.default_rng(3)
    u = rng.normal(size=3600)
    b, a = [0.0, 0.1], [1.0, -0.9]
    y = signal.lfilter(b, a, u)
    w, g = spectral_estimate(u, y, 1.0)
    _, true = signal.freqz(b, a, worN=w)
    assert np.abs(g[1:] - true[1:]).max() / np.abs(true).max() < 0.03  # leakage near 0 Hz


def test_crossval_samples_a_dead_time_exactly_as_identify_and_design_do() -> None:
    """K e^(-1.5 h s) / (T s + 1) after a unit step at row 0: the sampled response is
    K (1 - e^(-(k h - L) / T)) from k h > L, the dead time not rounded to 2 samples
    (crossval did that; identify/sampling and design/sampled did not)."""
    import math

    from quadtank_tui.core.delaytf import DelayTF
    from quadtank_tui.core.design.sampled import sample
    from quadtank_tui.core.identify.crossval import simulate_element

    K, T, h = 2.0, 30.0, 4.0
    L = 1.5 * h
    y = simulate_element(DelayTF((K,), (T, 1.0), L), np.ones(12), h)
    want = [K * (1 - math.exp(-(k * h - L) / T)) if k * h > L else 0.0 for k in range(12)]
    assert y == pytest.approx(want, abs=1e-12)
    m = sample(DelayTF((K,), (T, 1.0), L), h)  # x(k+1) = A x + B u, y = C x + Dd u
    x, ys = np.zeros(m.A.shape[0]), []
    for _ in range(12):
        ys.append(float(m.C @ x + m.Dd))
        x = m.A @ x + m.B.ravel()
    assert ys == pytest.approx(want, abs=1e-12)


def test_a_log_whose_references_move_is_said_to_be_closed_loop() -> None:
    from quadtank_tui.core.identify.feedback import closed_loop

    u = np.linspace(0.3, 0.4, 50)
    assert closed_loop([("open.log", {"u1": u, "y1": u, "r1": np.full(50, 0.5)})]) is None
    line = closed_loop([("open.log", {"u1": u}), ("pi.log", {"u1": u, "r1": np.repeat([0.5, 0.55], 25),
                                                            "r2": np.full(50, 0.4)})])
    assert line is not None and line.startswith("closed loop: the references move (r1 in pi.log)")
    assert "\n" not in line


def test_poles_are_reported_as_they_are_complex_pairs_named() -> None:
    from quadtank_tui.core.identify.report import pole_text

    text = pole_text(np.array([-0.0107, -0.0297, -0.0557 + 0.0599j, -0.0557 - 0.0599j]))
    assert text.startswith("T=93.5 s, T=33.7 s, complex pair -0.0557±0.0599j /s (wn 0.0818 rad/s, zeta 0.68)")
    assert "poles)" not in text and text.count("complex pair") == 1
