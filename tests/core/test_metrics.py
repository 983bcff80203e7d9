"""Loop figures from sampled signals, on hand-made responses with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from quadtank_tui.core.metrics import loop_metrics


def test_first_order_step_settles_where_the_exponential_says() -> None:
    t = np.arange(0.0, 400.0, 0.1)
    r = np.where(t >= 100.0, 0.7, 0.6)
    tau = 20.0
    y = np.where(t >= 100.0, 0.7 - 0.1 * np.exp(-(t - 100.0) / tau), 0.6)
    m = loop_metrics(t, y, r)
    assert m.step == pytest.approx(0.1) and m.step_time == pytest.approx(100.0)
    assert m.overshoot == 0.0
    assert m.settling_time == pytest.approx(tau * np.log(50.0), abs=0.11)  # 2 % band
    assert m.iae == pytest.approx(0.1 * tau, rel=1e-2)
    assert abs(m.final_error) < 1e-6


def test_overshoot_of_a_negative_step_and_no_settling() -> None:
    t = np.arange(10.0)
    r = np.array([0.5] * 2 + [0.3] * 8)
    y = np.array([0.5, 0.5, 0.45, 0.35, 0.27, 0.31, 0.30, 0.30, 0.30, 0.33])
    m = loop_metrics(t, y, r)
    assert m.step == pytest.approx(-0.2)
    assert m.overshoot == pytest.approx(15.0)
    assert m.settling_time is None
    assert m.final_error == pytest.approx(-0.03)


def test_no_step_and_bad_input() -> None:
    m = loop_metrics(np.arange(3.0), np.array([0.1, 0.2, 0.3]), np.array([0.3, 0.3, 0.3]))
    assert m.step is None and m.overshoot is None and m.iae == pytest.approx(0.3)
    with pytest.raises(ValueError):
        loop_metrics(np.arange(3.0), np.zeros(2), np.zeros(3))
