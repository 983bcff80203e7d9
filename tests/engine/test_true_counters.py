"""Overruns count samples that started late, never more than the samples, and the
summary of a paced virtual run says the speed it held next to the speed asked.

A ManualClock stands in for the machine: each sample costs 250 us of wall time
at x1000 with Ts 0.1 s (a wall period of 100 us), so every sample starts late and
2.5 slots go by per sample: x1000 x 100 / 250 = x400 held.  Before, the summary counted each
skipped slot as an overrun (more overruns than samples) and said nothing of speed.
"""

from __future__ import annotations

import re
from typing import Callable

import pytest

from quadtank_tui.engine.clock import CATCH_UP, ManualClock, RealTimeClock
from quadtank_tui.engine.commands import SetState
from quadtank_tui.engine.experiment import format_summary, summarize
from quadtank_tui.engine.runner import Engine


def test_a_clock_counts_late_samples_and_skipped_slots_apart() -> None:
    src = ManualClock(0.0)
    clock = RealTimeClock(0.1, src.now)
    clock.start()
    clock.tick()
    src.advance(0.35)                     # due at 0.1, starts at 0.35: 0.2 and 0.3 skipped
    assert clock.tick().missed == 2
    assert (clock.overruns, clock.skipped) == (1, 2)


def test_a_run_too_fast_for_the_machine_says_the_speed_it_held(make_engine: Callable[..., Engine],
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    src = ManualClock(0.0)

    def slow_sleep(dt: float) -> None:
        src.sleep(dt)

    engine = make_engine(clock="virtual", speed=1000.0, now=src.now, sleep=slow_sleep)
    sim = engine.loop.backend                 # the simulator: one write of the pumps a sample
    write = sim.write_pumps

    def costly_write(u: tuple[float, float]) -> None:  # every sample takes 250 us of wall time
        write(u)
        src.advance(250e-6)

    monkeypatch.setattr(sim, "write_pumps", costly_write)
    engine.submit(SetState("Run"))
    samples = engine.run_for(20.0)
    s = summarize(engine, 20.0)
    # 20 s of loop time: 200 slots of 0.1 s, sampled or skipped (the simulator's
    # time waits for the loop, so every sample is one slot of process time).
    assert s.samples == samples == 200
    # Every sample falls 150 us further behind: the first CATCH_UP (20 ms) of lag is
    # to be made up (no overrun, nothing skipped); the samples after that skip the
    # slots beyond it, and the run ends CATCH_UP behind (200 slots of 100 us).
    assert s.overruns == pytest.approx(s.samples - CATCH_UP / 150e-6, abs=2)
    assert s.behind == round(CATCH_UP / 100e-6)
    assert s.skipped + s.behind == pytest.approx(1.5 * s.samples, abs=2)
    assert s.speed == 1000.0 and s.speed_held == pytest.approx(400, rel=0.01)
    text = format_summary(s)
    assert f"{s.samples} samples, {s.overruns} overruns ({s.skipped} sampling slots skipped)" in text
    assert re.search(r"speed      x1000 asked, x(39\d|40\d) held", text)


def test_a_run_that_keeps_up_has_no_overruns_and_holds_its_speed(make_engine: Callable[..., Engine]) -> None:
    src = ManualClock(0.0)
    engine = make_engine(clock="virtual", speed=10.0, now=src.now, sleep=src.sleep)
    engine.submit(SetState("Run"))
    engine.run_for(2.0)
    s = summarize(engine, 2.0)
    assert (s.samples, s.overruns, s.skipped) == (20, 0, 0)
    assert "speed      x10 asked, x10 held" in format_summary(s)
