"""When samples are due: real time, virtual time, and a hand-driven time source.

A clock only *schedules*; it never sleeps.  The driver (engine/driver.py, the one
for sessions, the engine's thread and headless runs) asks :meth:`Clock.deadline`
for the monotonic wall time at which the next sample is due, waits however suits
it, and calls :meth:`Clock.tick` with the time the sample really started.  Time is injected
(style.md habit 2): every clock takes a ``now`` function, so tests drive a
:class:`ManualClock` instead of sleeping.

Jitter is the actual minus the scheduled start of a sample.  An overrun is a
sample that started late: so late that the next sample's slot had already begun.
The schedule then skips to the next deadline still in the future instead of
running the missed samples in a burst.  Overruns count samples (never more than
the samples taken); the deadlines skipped are counted apart (`skipped`).

A paced virtual clock may fall behind by up to its `catch_up` of wall time
(CATCH_UP) and make the slots up in a burst, without skipping them and without
an overrun: its process is the simulator, whose time is counted in samples, so a
burst is invisible to the plant.  At x1000 and 50 ms a slot is 50 us of wall
time, and a hiccup of the machine or of the session (an event-loop turn, a
publish, a fsync, the garbage collector) of a fraction of a millisecond would
otherwise lose its slots for good.  Only the lag beyond `catch_up` is skipped.
The speed it held is then asked x samples / (samples + skipped + `behind`), where
`behind` counts the slots the last sample was still late by: wall time, honest.
A real-time clock's catch_up is 0: a rig's samples are never bunched up.
"""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from typing import Callable, NamedTuple

Now = Callable[[], float]

#: The speed factors a virtual clock accepts (SetSpeed, --speed).
SPEED_MIN, SPEED_MAX = 1.0, 1000.0
#: The factors the UI's faster / slower keys step through (a 1-2-5 series: round
#: numbers a student can reason with, where doubling from 1 ends at 512).
SPEED_STEPS = (1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0)
#: Wall seconds a paced virtual clock may fall behind its schedule and still make
#: the slots up in a burst (at x1000 and 50 ms: 400 samples, made up within a
#: fraction of a second); beyond that the slots are skipped.
CATCH_UP = 0.02


def next_speed(speed: float, direction: int) -> float:
    """The step after `speed` going up (direction > 0) or down (< 0); a speed between
    steps (``--speed 3``) goes to the neighbouring step; the ends stay where they are."""
    if direction > 0:
        return next((s for s in SPEED_STEPS if s > speed), SPEED_STEPS[-1])
    return next((s for s in reversed(SPEED_STEPS) if s < speed), SPEED_STEPS[0])


class Timing(NamedTuple):
    """What :meth:`Clock.tick` measured for one sample (seconds).  The driver takes
    the plain tuple (:meth:`Clock.tick_values`)."""

    scheduled: float
    actual: float
    missed: int = 0

    @property
    def jitter(self) -> float:
        return self.actual - self.scheduled


class ManualClock:
    """A monotonic time source moved by hand: ``now()`` and ``sleep(dt)``.

    Stands in for ``time.monotonic``/``time.sleep`` in tests and in headless runs that
    must not wait: sleeping just moves the time on.
    """

    def __init__(self, start: float = 0.0) -> None:
        self.t = float(start)

    def now(self) -> float:
        return self.t

    def advance(self, dt: float) -> None:
        if dt < 0:
            raise ValueError(f"time does not run backwards (dt = {dt})")
        self.t += dt

    def sleep(self, dt: float) -> None:
        self.advance(max(0.0, dt))


class Clock(ABC):
    """The schedule of samples of period ``period`` seconds of process time."""

    realtime: bool = False
    #: Wall seconds of lag made up in a burst rather than skipped (0: skip at once).
    catch_up: float = 0.0

    def __init__(self, period: float, now: Now = time.monotonic) -> None:
        self._check_period(period)
        self.period = float(period)
        self.now = now
        self.overruns = 0   # samples that started late (beyond catch_up)
        self.skipped = 0    # deadlines that passed without their sample
        self.behind = 0     # slots the last sample was late by, to be made up (not skipped)
        self._next: float | None = None

    @staticmethod
    def _check_period(period: float) -> None:
        if not (isinstance(period, (int, float)) and math.isfinite(period) and period > 0):
            raise ValueError(f"sampling period must be a positive number of seconds, got {period!r}")

    @property
    def speed(self) -> float:
        """Process seconds per wall second (inf: as fast as possible)."""
        return 1.0

    def start(self) -> None:
        """The first sample is due now."""
        self._next = self.now()

    def deadline(self) -> float | None:
        """Monotonic time the next sample is due; None: due now (no waiting)."""
        if self._next is None:
            self.start()
        return self._next

    def tick(self) -> Timing:
        """A sample starts now: measure it and schedule the next one."""
        return Timing(*self.tick_values())

    def tick_values(self) -> tuple[float, float, int]:
        """:meth:`tick` as a plain (scheduled, actual, missed): the driver's every
        sample (no named tuple to make on the hot path)."""
        actual = self.now()
        scheduled = self.deadline()
        if scheduled is None:
            return (actual, actual, 0)
        step = self._wall_period()
        nxt = scheduled + step
        missed = 0
        late = actual - self.catch_up  # up to catch_up behind: the slots are made up in a burst
        if late >= nxt:  # whole slots went by beyond that: skip them, no burst
            missed = int((late - scheduled) // step)
            nxt = scheduled + (missed + 1) * step
            if nxt <= late:
                missed += 1
                nxt += step
        self.overruns += int(missed > 0)
        self.skipped += missed
        self.behind = int((actual - nxt) // step) + 1 if actual >= nxt else 0
        self._next = nxt
        return (scheduled, actual, missed)

    def set_period(self, period: float) -> None:
        """A new sampling time: the next sample stays where it is, later ones follow
        the new period."""
        self._check_period(period)
        self.period = float(period)

    @abstractmethod
    def _wall_period(self) -> float:
        """Wall seconds between samples."""


class RealTimeClock(Clock):
    """Absolute deadlines start + k * period on a monotonic clock: sleeping late for
    one sample never delays the following ones (no drift)."""

    realtime = True

    def _wall_period(self) -> float:
        return self.period


class VirtualClock(Clock):
    """Process time at `speed` x wall time (1..1000), or as fast as possible (None).

    Paced runs keep absolute deadlines in wall time like the real-time clock, so a
    slow sample is made up by the next ones' waits, and a lag of up to `catch_up`
    wall seconds by samples in a burst; a run that cannot keep up at all skips its
    deadlines beyond that (counted as skipped) rather than piling up.
    """

    realtime = False
    catch_up = CATCH_UP

    def __init__(self, period: float, speed: float | None = None, now: Now = time.monotonic) -> None:
        super().__init__(period, now)
        self._speed: float | None = None
        self.set_speed(speed)

    @property
    def speed(self) -> float:
        return math.inf if self._speed is None else self._speed

    def set_speed(self, speed: float | None) -> None:
        """New speed factor (None: unpaced); the next sample is due one new wall
        period after now."""
        if speed is not None:
            if isinstance(speed, bool) or not isinstance(speed, (int, float)) or not (
                SPEED_MIN <= speed <= SPEED_MAX
            ):
                raise ValueError(f"speed must be a factor {SPEED_MIN:g}..{SPEED_MAX:g}, got {speed!r}")
            speed = float(speed)
        self._speed = speed
        self.behind = 0
        self._next = None if speed is None else self.now() + self.period / speed

    def deadline(self) -> float | None:
        if self._speed is None:
            return None
        return super().deadline()

    def _wall_period(self) -> float:
        return self.period / self.speed

