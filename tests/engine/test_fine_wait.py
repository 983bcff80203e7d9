"""The driver's last wait before a deadline (engine/driver.py): a sleep, but a wait
shorter than SPIN_BELOW is spun, since a sleep of a few us takes 18-20 us."""

from __future__ import annotations

import time

import pytest

from quadtank_tui.engine import driver
from quadtank_tui.engine.driver import SPIN_BELOW, fine_wait


def test_a_wait_shorter_than_a_sleep_is_spun_and_a_longer_one_slept(monkeypatch: pytest.MonkeyPatch) -> None:
    slept: list[float] = []
    monkeypatch.setattr(driver.time, "sleep", lambda dt: slept.append(dt))
    deadline = time.monotonic() + SPIN_BELOW / 2
    fine_wait(deadline)
    assert slept == [] and time.monotonic() >= deadline   # spun until the deadline, not before
    fine_wait(time.monotonic() + 0.001)
    assert len(slept) == 1 and SPIN_BELOW < slept[0] <= 0.001
    fine_wait(time.monotonic() - 0.001)                   # already due: no wait at all
    assert len(slept) == 1
