"""Clock time on the trends' time axis (issue 17: "a time axis in round numbers
(e.g. seconds relative to now, or clock time)").

The pilot tests read the labels back off the rendered plot, as a student would:
the clock time of the column where u1 steps must be the wall clock at which the
step's sample was taken, across a pause, at 120x40 and 80x24.
"""

from __future__ import annotations

import re
from datetime import datetime
from typing import Any

import pytest

from uikit import Recording, make_app, plot_text

from quadtank_tui.engine import commands as c
from quadtank_tui.ui.widgets.trend_clock import (
    CLOCK_GAP, CLOCK_STEPS, MINUTES_GAP, ClockMap, clock_label, clock_ticks, hms, local_offset, process_ticks,
)
from quadtank_tui.ui.widgets.trends import Trend

#: The wall clock of process time 0 in the pilot tests (local time, as the labels).
BASE = datetime(2026, 11, 23, 14, 0, 0).timestamp()
H = 0.1  # the preset's sampling time, s


def local(wall: float) -> float:
    """Seconds since local midnight (what a label names)."""
    return (wall + local_offset(wall)) % 86400


def seconds_of(label: str) -> float:
    parts = [int(p) for p in label.split(":")] + [0]
    return parts[0] * 3600 + parts[1] * 60 + parts[2]


# --- the map from process time to the wall clock ---------------------------------------------

def test_a_steady_run_keeps_two_anchors_and_a_pause_adds_its_own() -> None:
    clock = ClockMap()
    for k in range(3000):  # 300 s at x1
        clock.note(k * H, BASE + k * H)
    assert len(clock) == 2 and clock.since == 0.0
    for k in range(3000, 6000):  # then 10 minutes paused, then 300 s at x10
        clock.note(k * H, BASE + 600.0 + 300.0 + (k - 3000) * H / 10)
    assert len(clock) == 4
    assert clock.wall(150.0) == pytest.approx(BASE + 150.0)
    assert clock.wall(450.0) == pytest.approx(BASE + 900.0 + 15.0)
    assert clock.process_time(BASE + 915.0) == pytest.approx(450.0)
    clock.note(5999 * H, BASE + 950.0)  # the newest sample seen again (paused) changes nothing
    assert len(clock) == 4 and clock.wall(5999 * H) == pytest.approx(BASE + 900.0 + 299.9)
    clock.note(0.0, BASE + 2000.0)  # a Reset: process time starts again
    assert len(clock) == 1 and clock.wall(0.0) == BASE + 2000.0


def test_a_pause_stands_and_its_clock_times_have_no_sample() -> None:
    clock = ClockMap()
    clock.note(0.0, BASE)
    clock.note(10.0, BASE + 10.0)
    for wall in (20.0, 45.0, 70.0):  # paused 60 s: the sample at 10 s stays the newest
        clock.stand(10.0, BASE + wall)
    clock.note(10.1, BASE + 70.1)
    clock.note(20.0, BASE + 80.0)
    assert len(clock) == 4
    assert clock.paused_at(BASE + 40.0) and not clock.paused_at(BASE + 5.0) and not clock.paused_at(BASE + 75.0)
    assert clock.wall(15.0) == pytest.approx(BASE + 75.0) and clock.wall(5.0) == pytest.approx(BASE + 5.0)
    ticks = clock_ticks(clock, 0.0, 0.5, 41)  # 0..20 s: labels every 5 s of clock, none in the pause
    values = [seconds_of(label) - local(BASE) for label in ticks.labels]
    assert ticks.step == 5 and values == [0.0, 5.0, 10.0, 75.0, 80.0], ticks
    assert ticks.columns == (0, 10, 20, 30, 40)  # 14:01:15 is the sample at 15 s


def test_clock_labels_are_round_and_on_the_columns_of_their_samples() -> None:
    clock = ClockMap()
    clock.note(0.0, BASE + 7.3)  # the run started at 14:00:07.3
    clock.note(3600.0, BASE + 3607.3)
    for columns, per_column in ((113, 30 / 11), (31, 10.0), (60, 1.0), (80, 60.0)):
        t_first = 1000.0
        ticks = clock_ticks(clock, t_first, per_column, columns)
        assert ticks.step in CLOCK_STEPS and len(ticks.labels) >= 2, (columns, per_column, ticks)
        gap = CLOCK_GAP if ticks.step < 60 else MINUTES_GAP
        assert all(b - a >= gap for a, b in zip(ticks.columns, ticks.columns[1:]))
        for column, label in zip(ticks.columns, ticks.labels):
            assert len(label) == (8 if ticks.step < 60 else 5), label
            value = seconds_of(label)
            assert value % ticks.step == 0, label
            # the sample of that clock time is in that column (half a column either side)
            t = clock.process_time(BASE + (value - local(BASE)))
            assert abs(t - (t_first + column * per_column)) <= per_column / 2 + 1e-6, (label, column)


def test_no_label_before_the_clock_is_known_and_process_time_as_h_mm_ss() -> None:
    clock = ClockMap()
    clock.note(500.0, BASE)
    clock.note(800.0, BASE + 300.0)
    ticks = clock_ticks(clock, 400.0, 3.0, 134)  # 400..799 s: the first 100 s have no clock
    assert ticks.columns[0] >= 100 / 3 - 0.5
    assert ticks.labels[0] == clock_label(local(BASE), True)
    p = process_ticks(-20.0, 2.0, 70)  # -20..118 s: nothing before the start
    assert p.labels == ("0:00:00", "0:00:30", "0:01:00", "0:01:30") and p.columns == (10, 25, 40, 55)
    assert hms(3725.0, True) == "1:02:05" and hms(3725.0, False) == "1:02"
    assert clock_label(50400.0 + 62.0, True) == "14:01:02" and clock_label(3600.0 * 9, False) == "09:00"


# --- read off the screen ----------------------------------------------------------------------

def x_labels(plot: str) -> list[tuple[int, str]]:
    """The time axis as drawn: (column, label) of each tick, the column from the
    plot's left edge."""
    lines = plot.splitlines()
    axis = next(n for n, line in enumerate(lines) if "└" in line)
    ticks = [n for n, ch in enumerate(lines[axis]) if ch == "┬"]
    found = []
    for m in re.finditer(r"\d+:\d\d(?::\d\d)?", lines[axis + 1]):
        middle = (m.start() + m.end() - 1) / 2
        tick = min(ticks, key=lambda n: abs(n - middle))
        assert abs(tick - middle) <= 1, (m.group(), ticks, lines[axis + 1])
        found.append((tick, m.group()))
    assert len(found) == len(ticks), lines[axis:axis + 2]
    return found


def step_column(plot: str) -> int:
    """The column where the curve leaves its first row (u1 steps up)."""
    lines = plot.splitlines()
    rows = [(n, line) for n, line in enumerate(lines) if "┤" in line]
    drawn = [(n, line) for n, line in rows if any(0x2801 <= ord(ch) <= 0x28FF for ch in line.partition("┤")[2])]
    n, top = drawn[0]  # the higher level, after the step
    start = top.index("┤") + 1
    return next(col for col in range(start, len(top)) if 0x2801 <= ord(top[col]) <= 0x28FF)


def clock_at(labels: list[tuple[int, str]], column: int) -> float:
    """The clock time of a column, between the two labels around it."""
    (c0, l0), (c1, l1) = next((a, b) for a, b in zip(labels, labels[1:]) if a[0] <= column <= b[0])
    v0, v1 = seconds_of(l0), seconds_of(l1)
    return v0 + (column - c0) * (v1 - v0) / (c1 - c0)


async def run(engine: Recording, app: Any, pilot: Any, seconds: float, wall: list[float]) -> None:
    """`seconds` of process time at x1, the screen looking every 25 s (the real
    screen looks at every refresh; at a steady speed the clock in between is a
    straight line, so this is the same map)."""
    end = engine.snapshot().t + seconds
    while engine.snapshot().t < end - 1e-9:
        engine.run_for(min(25.0, end - engine.snapshot().t))
        app.main.refresh_view()
    await pilot.pause()


@pytest.mark.parametrize("size", [(120, 40), (80, 24)])
async def test_the_clock_axis_reads_back_the_wall_clock_of_a_step_after_a_pause(
        engine: Recording, size: tuple[int, int]) -> None:
    """100 s of running from 14:00:00, a minute's pause, then u1 steps 0.3 -> 0.5
    at process time 200 s: the step's column reads 14:04:20 on the clock axis."""
    pause = [0.0]
    app = make_app(engine)
    # the wall clock of the newest sample (the snapshot's t is that of the next one)
    app.main.epoch_clock = lambda: BASE + engine.snapshot().t - H + pause[0]
    async with app.run_test(size=size) as pilot:
        engine.submit(c.SetState("Run"))
        engine.step()
        app.main.refresh_view()  # the first sample, 14:00:00
        await run(engine, app, pilot, 100.0 - H, pause)
        engine.submit(c.SetState("Pause"))
        pause[0] += 60.0
        app.main.refresh_view()
        engine.submit(c.SetState("Run"))
        engine.step()
        app.main.refresh_view()  # the first sample after the pause
        await run(engine, app, pilot, 100.0 - H, pause)
        engine.submit(c.SetParams({"REFERENCE ONE.Mean": 0.5}))
        await run(engine, app, pilot, 130.0, pause)
        upper = app.main.query_one("#upper", Trend)
        assert upper.border_title == "live, t in s"
        await pilot.press("c")
        await pilot.pause()
        plot = plot_text(upper)
        assert upper.border_title == "live, clock time"
        assert str(upper.border_subtitle).endswith("c clock")
        labels = x_labels(plot)
        values = [seconds_of(label) for _, label in labels]
        step = min(b - a for a, b in zip(values, values[1:]))
        assert len(labels) >= (2 if size[0] < 100 else 5) and all(v % step == 0 for v in values), labels
        assert all(len(label) == (8 if step < 60 else 5) for _, label in labels), labels
        # no sample was taken during the pause (14:01:40 to 14:02:40)
        assert not any(local(BASE + 100.0) < v < local(BASE + 160.0) for v in values), labels
        # the step: taken at 14:04:20, read back within a column and a label's rounding
        read = clock_at(labels, step_column(plot))
        per_column = step / min(b[0] - a[0] for a, b in zip(labels, labels[1:]))
        assert abs(read - local(BASE + 260.0)) <= 1.5 * per_column + 1.0, (size, read, plot)
        engine.submit(c.SetState("Pause"))
        await pilot.press("left")  # scrolled back: the title names the clock times in view
        await pilot.pause()
        assert re.fullmatch(r"viewing 14:0\d:\d\d-14:0\d:\d\d, End to return", upper.border_title), upper.border_title
        await pilot.press("end", "c")  # live, and back to seconds before now
        await pilot.pause()
        assert upper.border_title == "live, t in s"
        assert plot_text(upper).splitlines()[-1].split()[-1] == "0"


async def test_history_from_before_the_screen_is_in_process_time(engine: Recording) -> None:
    """Attached to a run already 400 s on: its history has no clock, so the axis
    shows process time since the start, and the title from when the clock is known."""
    engine.submit(c.SetState("Run"))
    engine.run_for(250.0)
    engine.submit(c.SetParams({"REFERENCE ONE.Mean": 0.5}))
    engine.run_for(150.0)
    app = make_app(engine)
    app.main.epoch_clock = lambda: BASE + engine.snapshot().t - H
    async with app.run_test(size=(120, 40)) as pilot:
        await run(engine, app, pilot, 10.0, [0.0])
        await pilot.press("c")
        await pilot.pause()
        upper = app.main.query_one("#upper", Trend)
        assert upper.border_title == "live, t h:m:s, clock from " + clock_label(local(BASE + 400.0 - H), True)
        plot = plot_text(upper)
        labels = x_labels(plot)
        assert all(re.fullmatch(r"0:0\d:[0-5]0", label) for _, label in labels), labels
        read = clock_at(labels, step_column(plot))
        assert abs(read - 250.0) <= 5.0, (read, plot)
