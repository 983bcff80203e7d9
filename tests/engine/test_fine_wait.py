"""The driver's last wait before a deadline (engine/driver.py): a sleep, but a wait
shorter than SPIN_BELOW is spun, since a sleep of a few us takes 18-20 us; a
real-time clock's last SPIN_LAST is spun too, since a sleeping core wakes late; and
the event loop never gets a turn between a wait's end and its sample."""

from __future__ import annotations

import asyncio
import time
from typing import Callable

import pytest

from quadtank_tui.engine import driver
from quadtank_tui.engine.driver import FINE_WAIT, SPIN_BELOW, SPIN_LAST, Driver, LoopTime, fine_wait
from quadtank_tui.engine.runner import Engine


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


class _Wall:
    """A stand-in for time.monotonic and time.sleep: each look at the time moves it
    on by 1 us (so a spin ends), a sleep by what it was asked."""

    TICK = 1e-6

    def __init__(self) -> None:
        self.t = 1000.0
        self.sleeps: list[tuple[float, float]] = []   # (asked at, ends at)

    def monotonic(self) -> float:
        self.t += self.TICK
        return self.t

    def sleep(self, dt: float) -> None:
        self.sleeps.append((self.t, self.t + dt))
        self.t += dt


def _drive_on(wall: _Wall, engine: Engine, samples: int) -> list[tuple[float, float]]:
    """(deadline, start) of each sample of a drive on `wall`'s time, no event loop."""
    starts: list[tuple[float, float]] = []
    clock = engine.clock

    def before(_: LoopTime) -> None:
        deadline = clock.deadline()
        assert deadline is not None
        starts.append((deadline, wall.t))

    Driver(engine, samples=samples, before=before).run()
    return starts


def test_a_real_time_clock_sleeps_until_spin_last_before_its_deadline_and_spins_the_rest(
        make_engine: Callable[..., Engine], monkeypatch: pytest.MonkeyPatch) -> None:
    """Its sleep ends SPIN_LAST before the deadline (a woken core came out of idle
    0.07-0.17 ms late, p50-p99), the spin on the deadline; a virtual clock, whose
    jitter no plant sees, sleeps to its deadline."""
    wall = _Wall()
    now, sleep = wall.monotonic, wall.sleep   # the same objects: the engine is paced on "the wall"
    monkeypatch.setattr(driver.time, "monotonic", now)
    monkeypatch.setattr(driver.time, "sleep", sleep)
    engine = make_engine(clock="realtime", now=now, sleep=sleep)
    engine.clock.set_period(0.01)
    assert engine.wall_paced
    starts = _drive_on(wall, engine, 4)
    assert len(wall.sleeps) == 3                          # the first sample is due at once
    for (deadline, start), (_, woke) in zip(starts[1:], wall.sleeps):
        assert woke == pytest.approx(deadline - SPIN_LAST, abs=20 * _Wall.TICK)
        assert deadline <= start <= deadline + 20 * _Wall.TICK   # spun until the deadline, not before

    virtual = _Wall()
    now, sleep = virtual.monotonic, virtual.sleep
    monkeypatch.setattr(driver.time, "monotonic", now)
    monkeypatch.setattr(driver.time, "sleep", sleep)
    paced = make_engine(clock="virtual", speed=5.0, now=now, sleep=sleep)
    assert paced.wall_paced and not paced.clock.realtime
    starts = _drive_on(virtual, paced, 4)
    assert len(virtual.sleeps) == 4                       # a paced clock's first sample is a period away
    for (deadline, start), (_, woke) in zip(starts, virtual.sleeps):
        assert woke == pytest.approx(deadline, abs=20 * _Wall.TICK) and start >= deadline


class _Traced(Driver):
    """A driver that notes when each of its event-loop waits ended."""

    def __init__(self, engine: Engine, events: list[str], **kwargs: object) -> None:
        super().__init__(engine, **kwargs)  # type: ignore[arg-type]
        self.events = events

    async def _wait(self, aloop: asyncio.AbstractEventLoop, until: float) -> None:
        await super()._wait(aloop, until)
        self.events.append("waited")


def test_the_event_loop_gets_no_turn_between_a_wait_and_its_sample(make_engine: Callable[..., Engine]) -> None:
    """A client with lines waiting asks for a turn at once (`urgent`; a turn may
    encode a ring buffer's part, 1 ms): it gets it right after a sample, never in
    the FINE_WAIT before the next one (the fine wait and the sample come straight
    after the event loop's wait, with nothing of the loop's in between)."""
    engine = make_engine(clock="realtime")
    engine.clock.set_period(0.02)
    events: list[str] = []
    aloop = asyncio.new_event_loop()

    def turn() -> None:  # runs at every turn of the event loop
        if not events or events[-1] != "turn":
            events.append("turn")
        aloop.call_soon(turn)

    aloop.call_soon(turn)
    drive = _Traced(engine, events, samples=4, urgent=lambda: True,
                    before=lambda _: events.append("sample"), after=lambda: events.append("published"))
    drive.serve(aloop)
    waits = [i for i, e in enumerate(events) if e == "waited"]
    assert waits and "turn" in events
    for i in waits:
        assert events[i + 1] in ("sample", "waited"), events[i - 2:i + 4]   # woken early: it waits again
    for i, e in enumerate(events[:-1]):
        if e == "sample":
            assert events[i + 1] == "published"
    assert FINE_WAIT < 0.02
