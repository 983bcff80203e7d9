"""Ring buffers: fixed memory, last N seconds as read-only copies."""

from __future__ import annotations

import numpy as np
import pytest

from quadtank_tui.engine.handle import SIGNALS
from quadtank_tui.engine.history import History


def test_wraps_at_capacity_and_keeps_the_newest_in_order() -> None:
    h = History(5000)
    nbytes = h.nbytes
    for k in range(12_345):
        h.append([k * 0.1] + [float(k)] * (len(SIGNALS) - 1))
    assert len(h) == 5000 and h.nbytes == nbytes
    data = h.last()
    assert set(data) == set(SIGNALS)
    assert data["y1"][0] == 12_345 - 5000 and data["y1"][-1] == 12_344
    assert np.all(np.diff(data["t"]) > 0)


def test_last_seconds_and_copies() -> None:
    h = History(5000)
    for k in range(100):
        h.append([k * 0.5] + [k] * (len(SIGNALS) - 1))
    recent = h.last(10.0)
    assert recent["t"][0] == pytest.approx(39.5) and recent["t"][-1] == pytest.approx(49.5)
    assert len(recent["u2"]) == 21
    with pytest.raises(ValueError):
        recent["y1"][0] = 1.0  # read-only
    h.append([50.0] + [7.0] * (len(SIGNALS) - 1))
    assert recent["y1"][-1] == 99  # a copy: later samples do not show up in it
    h.clear()
    assert len(h.last()["t"]) == 0


def test_capacity_of_at_least_5000_samples() -> None:
    with pytest.raises(ValueError):
        History(4999)
