"""Clock time on the trends' time axis (issue 17: "a time axis in round numbers
(e.g. seconds relative to now, or clock time)").

What a student reads off a clock axis is the wall clock at which each sample was
taken ("the step went in at 14:02:30"), at any speed-up and across pauses.  The
history holds process time only, so the Main screen notes, as each new sample
arrives, the process time of the newest sample and the wall clock it was taken
at (`ClockMap.note`); a sample in between is placed by linear interpolation, to
within one screen refresh.  While a simulation is paused no sample is taken:
the screen notes that the newest one is still the newest (`ClockMap.stand`), and
no clock time of the pause is labelled (it has no column).  Anchors on a
straight line (a steady speed) are merged, so hours of running keep a handful.

Samples from before the screen started watching (a lab session it attached to)
have no known clock: a view that reaches back before the first anchor shows
process time since the start as H:MM:SS instead, and its title says from when
the clock is known (trends.py).

Both kinds of labels are round (:00 :15 :30 ..., or 0:05:00 0:10:00 ...) and
sit on the column of the sample taken at that time (`round_ticks`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

#: Round label steps of a clock or H:MM:SS axis, s.
CLOCK_STEPS = (1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600, 7200, 10800, 21600, 43200, 86400)
#: Least columns from one label to the next: "12:34:56" and a space or two; "12:34"
#: (steps of a minute or more) and a space or two.
CLOCK_GAP = 10
MINUTES_GAP = 7
#: An anchor that strays less than this from the line through its neighbours
#: is merged into it (wall seconds).
TOLERANCE = 0.05
#: Anchors kept at most (the oldest go first): a pause or a speed change each.
MAX_ANCHORS = 4096


class ClockMap:
    """Process time (s) -> the wall clock (epoch s) at which the sample was taken,
    from the anchors the screen noted."""

    def __init__(self) -> None:
        self._t: list[float] = []
        self._wall: list[float] = []

    def note(self, t: float, wall: float) -> None:
        """The sample at process time `t` was taken at `wall`.  An earlier `t` than
        the last (a Reset, a Load) starts the map again."""
        if self._t and t < self._t[-1]:
            self.clear()
        if self._t and t == self._t[-1]:
            return  # the same sample, seen again
        if len(self._t) >= 2:
            (t0, t1), (w0, w1) = self._t[-2:], self._wall[-2:]
            if abs(w0 + (wall - w0) * (t1 - t0) / (t - t0) - w1) < TOLERANCE:
                self._t[-1], self._wall[-1] = t, wall  # on the line: the middle one goes
                return
        self._t.append(t)
        self._wall.append(max(wall, self._wall[-1]) if self._wall else wall)
        if len(self._t) > MAX_ANCHORS:
            del self._t[0], self._wall[0]

    def stand(self, t: float, wall: float) -> None:
        """Paused: at `wall` the sample at `t` is still the newest."""
        if not self._t or t != self._t[-1]:
            self.note(t, wall)
        elif len(self._t) >= 2 and self._t[-2] == t:
            self._wall[-1] = max(wall, self._wall[-1])  # the pause goes on
        elif wall - self._wall[-1] > TOLERANCE:
            self._t.append(t)
            self._wall.append(wall)

    def paused_within(self, start: float, end: float) -> float:
        """Wall seconds of pauses between `start` and `end`."""
        t, w = np.asarray(self._t), np.asarray(self._wall)
        standing = t[:-1] == t[1:]
        overlap = np.minimum(w[1:], end) - np.maximum(w[:-1], start)
        return float(np.clip(overlap[standing], 0.0, None).sum())

    def paused_at(self, wall: float) -> bool:
        """Whether `wall` falls in a pause (no sample then)."""
        t, w = np.asarray(self._t), np.asarray(self._wall)
        standing = (t[:-1] == t[1:]) & (w[:-1] + TOLERANCE < wall) & (wall < w[1:] - TOLERANCE)
        return bool(standing.any())

    def clear(self) -> None:
        self._t.clear()
        self._wall.clear()

    def __len__(self) -> int:
        return len(self._t)

    @property
    def since(self) -> float | None:
        """The earliest process time whose clock is known (None: none yet)."""
        return self._t[0] if self._t else None

    def wall(self, t: float) -> float:
        """The wall clock of process time `t` (at the ends: the end's clock)."""
        return float(np.interp(t, self._t, self._wall))

    def process_time(self, wall: float) -> float:
        """The process time of the sample taken at `wall` (the first, across a pause)."""
        return float(np.interp(wall, self._wall, self._t))


def local_offset(wall: float) -> float:
    """Seconds the local clock is ahead of UTC at `wall` (round local times are
    what the labels name, also in a half-hour time zone)."""
    return float(time.localtime(wall).tm_gmtoff)


def hms(seconds: float, with_seconds: bool) -> str:
    """12:05:30 (or 12:05), hours not wrapped: 0:05:30 of process time, 26:00:00."""
    s = int(round(seconds))
    h, m, sec = s // 3600, s // 60 % 60, s % 60
    return f"{h}:{m:02d}:{sec:02d}" if with_seconds else f"{h}:{m:02d}"


def clock_label(local: float, with_seconds: bool) -> str:
    """A local clock time (seconds since a local midnight) as HH:MM:SS or HH:MM."""
    return hms(local % 86400, with_seconds).zfill(8 if with_seconds else 5)


def wall_label(clock: ClockMap, t: float) -> str:
    """The local clock time of process time `t`, HH:MM:SS."""
    wall = clock.wall(t)
    return clock_label(wall + local_offset(wall), True)


@dataclass(frozen=True)
class Ticks:
    """Labelled columns (from the left) and the label step, s."""

    columns: tuple[int, ...]
    labels: tuple[str, ...]
    step: float


def round_ticks(t_first: float, per_column: float, columns: int, *, value: Callable[[float], float],
                time_of: Callable[[float], float], label: Callable[[float, bool], str],
                start: float | None = None, skip: Callable[[float], bool] = lambda v: False,
                idle: Callable[[float, float], float] = lambda v0, v1: 0.0) -> Ticks:
    """Labels at round values of a non-decreasing `value` of process time, each
    on the column holding the sample of that value.

    Column j holds process time t_first + j per_column.  The step is the least of
    CLOCK_STEPS that leaves room for its labels (CLOCK_GAP columns a label with
    seconds, MINUTES_GAP without) on average; a label closer than that to the
    previous one (after a pause the clock jumps) is left out, and so is a value
    `skip` says has no sample; `idle` is how much of a span of values has none
    (a pause: it takes no columns).  Nothing before process time `start` is labelled."""
    t_last = t_first + (columns - 1) * per_column
    t_from = t_first if start is None else max(t_first, start)
    v0, v1 = value(t_from), value(t_last)
    if not (t_last > t_from and v1 > v0):
        return Ticks((), (), 0.0)
    columns_per_unit = (t_last - t_from) / max(v1 - v0 - idle(v0, v1), 1e-9) / per_column
    step = float(next((c for c in CLOCK_STEPS if c * columns_per_unit >= _gap(c)), CLOCK_STEPS[-1]))
    gap = _gap(step)
    kept: list[int] = []
    labels: list[str] = []
    for n in range(math.ceil(v0 / step - 1e-9), math.floor(v1 / step + 1e-9) + 1):
        if skip(n * step):
            continue
        column = round((time_of(n * step) - t_first) / per_column)
        if 0 <= column < columns and (not kept or column - kept[-1] >= gap):
            kept.append(column)
            labels.append(label(n * step, step < 60))
    return Ticks(tuple(kept), tuple(labels), step)


def _gap(step: float) -> int:
    return CLOCK_GAP if step < 60 else MINUTES_GAP


def clock_ticks(clock: ClockMap, t_first: float, per_column: float, columns: int) -> Ticks:
    """Round local clock times of the samples in view (the clock must be known
    from `t_first` on: else `process_ticks`)."""
    offset = local_offset(clock.wall(t_first + (columns - 1) * per_column))
    return round_ticks(t_first, per_column, columns,
                       value=lambda t: clock.wall(t) + offset,
                       time_of=lambda local: clock.process_time(local - offset),
                       label=clock_label, start=clock.since, skip=lambda local: clock.paused_at(local - offset),
                       idle=lambda a, b: clock.paused_within(a - offset, b - offset))


def process_ticks(t_first: float, per_column: float, columns: int) -> Ticks:
    """Round process times since the start, as H:MM:SS (or H:MM)."""
    return round_ticks(t_first, per_column, columns, value=lambda t: t, time_of=lambda t: t, label=hms, start=0.0)
