"""Clocks schedule on an injected time source: no sleeps, exact numbers."""

from __future__ import annotations

import math

import pytest

from quadtank_tui.engine.clock import CATCH_UP, ManualClock, RealTimeClock, VirtualClock


def test_realtime_deadlines_are_absolute_and_never_drift() -> None:
    src = ManualClock(100.0)
    clock = RealTimeClock(0.05, src.now)
    clock.start()
    jitters = []
    for k in range(1000):
        due = clock.deadline()
        assert due is not None  # a real-time clock always has a next deadline
        src.sleep(due - src.now())
        src.advance(0.0003 if k % 3 else 0.0011)  # wakes a little late, by varying amounts
        jitters.append(clock.tick().jitter)
    # The 1000th deadline is exactly start + 1000 periods: lateness never accumulates.
    assert clock.deadline() == pytest.approx(100.0 + 1000 * 0.05, abs=1e-9)
    assert max(jitters) == pytest.approx(0.0011) and min(jitters) == pytest.approx(0.0003)
    assert clock.overruns == 0


def test_a_late_sample_is_an_overrun_and_the_schedule_skips_without_a_burst() -> None:
    src = ManualClock(0.0)
    clock = RealTimeClock(0.1, src.now)
    clock.start()
    clock.tick()                      # sample 0 at 0.0; next due 0.1
    src.advance(0.35)                 # stalled: 0.1, 0.2, 0.3 went by
    timing = clock.tick()
    assert timing.jitter == pytest.approx(0.25) and timing.missed == 2
    assert (clock.overruns, clock.skipped) == (1, 2)   # one late sample, two slots skipped
    assert clock.deadline() == pytest.approx(0.4)   # the next future deadline, on the grid
    due = clock.deadline()
    assert due is not None
    src.sleep(due - src.now())
    assert clock.tick().missed == 0 and clock.overruns == 1


def test_period_change_keeps_the_next_deadline() -> None:
    src = ManualClock(0.0)
    clock = RealTimeClock(1.0, src.now)
    clock.start()
    clock.tick()
    clock.set_period(0.25)
    assert clock.deadline() == 1.0
    src.sleep(1.0)
    clock.tick()
    assert clock.deadline() == 1.25
    with pytest.raises(ValueError):
        clock.set_period(0.0)


def test_virtual_clock_unpaced_and_paced() -> None:
    src = ManualClock(0.0)
    fast = VirtualClock(0.1, None, src.now)
    assert fast.deadline() is None and fast.speed == math.inf
    assert fast.tick().jitter == 0.0
    paced = VirtualClock(1.0, 10.0, src.now)
    assert paced.deadline() == pytest.approx(0.1)   # 1 s of process time = 0.1 s wall
    src.sleep(0.1)
    paced.tick()
    assert paced.deadline() == pytest.approx(0.2)
    paced.set_speed(1000)
    assert paced.deadline() == pytest.approx(0.101)
    for bad in (0.5, 1001, True, "fast"):
        with pytest.raises(ValueError):
            paced.set_speed(bad)  # type: ignore[arg-type]
    assert paced.speed == 1000


def test_manual_clock_does_not_run_backwards() -> None:
    src = ManualClock()
    src.sleep(-1.0)
    assert src.now() == 0.0
    with pytest.raises(ValueError):
        src.advance(-0.1)


def test_speed_steps_are_1_2_5_and_stop_at_the_ends() -> None:
    from quadtank_tui.engine.clock import SPEED_STEPS, next_speed

    up, speed = [], 1.0
    for _ in range(10):
        speed = next_speed(speed, 1)
        up.append(speed)
    assert up == [2, 5, 10, 20, 50, 100, 200, 500, 1000, 1000]
    assert [next_speed(s, -1) for s in SPEED_STEPS] == [1, 1, 2, 5, 10, 20, 50, 100, 200, 500]
    # A speed between the steps (quadtank --speed 3) goes to its neighbours.
    assert (next_speed(3.0, 1), next_speed(3.0, -1)) == (5, 2)


def _hiccup(clock: RealTimeClock | VirtualClock, src: ManualClock, *, cost: float, hiccup: float,
            samples: int) -> list[int]:
    """`samples` samples each costing `cost` s of wall time, the 10th held up by
    `hiccup` s more; each waits for its deadline.  The slots each one missed."""
    clock.start()
    missed = []
    for k in range(samples):
        due = clock.deadline()
        assert due is not None
        src.sleep(due - src.now())
        missed.append(clock.tick().missed)
        src.advance(cost + (hiccup if k == 10 else 0.0))
    return missed


def test_a_virtual_clock_makes_a_hiccup_up_in_a_burst_without_skipping() -> None:
    # x1000 at 50 ms: a slot every 50 us, a sample costs 40 us; one sample is held
    # up 0.3 ms (an event-loop turn, a fsync): 6 slots behind, made up by the next
    # samples running back to back (10 us gained each), none skipped.
    src = ManualClock(0.0)
    clock = VirtualClock(0.05, 1000.0, src.now)
    missed = _hiccup(clock, src, cost=40e-6, hiccup=0.3e-3, samples=100)
    assert sum(missed) == 0 and (clock.overruns, clock.skipped) == (0, 0)
    # Back on schedule after 0.29 ms / 10 us = 29 samples: 100 samples took 100 slots.
    assert clock.behind == 0
    assert clock.deadline() == pytest.approx(100 * 50e-6, abs=1e-12)
    assert src.now() < clock.deadline()  # type: ignore[operator]


def test_a_real_time_clock_still_skips_the_same_hiccup() -> None:
    src = ManualClock(0.0)
    clock = RealTimeClock(50e-6, src.now)
    missed = _hiccup(clock, src, cost=40e-6, hiccup=0.3e-3, samples=100)
    # The held-up sample's successor starts 0.29 ms late: 5 slots skipped, one overrun, no burst.
    assert missed[11] == 5 and sum(missed) == 5
    assert (clock.overruns, clock.skipped, clock.behind) == (1, 5, 0)


def test_a_virtual_clock_skips_only_the_lag_beyond_its_catch_up() -> None:
    # A stall of 0.1 s at x1000 (2000 slots of 50 us): CATCH_UP of it is made up,
    # the rest skipped at once.
    src = ManualClock(0.0)
    clock = VirtualClock(0.05, 1000.0, src.now)
    clock.start()
    clock.tick()
    src.advance(0.1)
    timing = clock.tick()
    assert timing.missed == round((0.1 - CATCH_UP) / 50e-6) - 1
    assert clock.behind == round(CATCH_UP / 50e-6)
    # Every slot of wall time is accounted for: sampled, skipped or still behind.
    assert 2 + clock.skipped + clock.behind == round(0.1 / 50e-6) + 1
