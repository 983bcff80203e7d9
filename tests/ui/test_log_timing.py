"""The Logging window says how long the points take and when the log ends."""

from __future__ import annotations

import dataclasses
from datetime import datetime

from textual.widgets import Static

from bursts import burst
from uikit import Recording, make_app

from quadtank_tui.engine import commands as c
from quadtank_tui.engine.snapshot import LogStatus
from quadtank_tui.ui.log_timing import duration_text, log_timing
from quadtank_tui.ui.windows.logging import LoggingWindow

NOW = datetime(2026, 1, 5, 10, 0, 0)


def test_durations_read_as_a_person_says_them() -> None:
    assert [duration_text(s) for s in (0.5, 45, 60, 90, 600, 3600, 7500)] == \
        ["0.5 s", "45 s", "1 min", "1 min 30 s", "10 min", "1 h", "2 h 5 min"]


def test_a_log_started_now_running_at_x1(engine: Recording) -> None:
    snap = dataclasses.replace(engine.snapshot(), speed=1.0, state="Run")
    assert log_timing(600, snap, NOW) == (
        "600 points x Ts 0.1 s = 1 min of process time\n"
        "LogOn now ends at 10:01:00 (in 1 min)")


def test_paused_at_a_speed_up(engine: Recording) -> None:
    snap = dataclasses.replace(engine.snapshot(), speed=10.0, state="Pause")
    assert log_timing(600, snap, NOW) == (
        "600 points x Ts 0.1 s = 1 min of process time\n"
        "LogOn now ends 6 s after Run (x10, now paused)")


def test_a_running_log_ends_after_the_rows_left(engine: Recording) -> None:
    log = LogStatus(active=True, rows=100, points=600)
    snap = dataclasses.replace(engine.snapshot(), speed=2.0, state="Run", log=log)
    assert log_timing(5000, snap, NOW) == (
        "5000 points x Ts 0.1 s = 8 min 20 s of process time\n"
        "This log ends at 10:00:25 (x2, in 25 s)")


def test_no_points_no_promise(engine: Recording) -> None:
    assert log_timing(None, engine.snapshot(), NOW) == ""


async def test_the_window_follows_the_points_field_and_the_speed(engine: Recording) -> None:
    engine.submit(c.SetParams({"SAMPLING TIME.TSamp": 500}))
    engine.submit(c.SetSpeed(5.0))
    engine.submit(c.SetState("Run"))
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await burst(pilot, "l")
        window = app.screen
        assert isinstance(window, LoggingWindow)
        window.now = lambda: NOW
        await burst(pilot, *"1200")                 # Points: select-on-focus, replaced
        timing = window.query_one("#log-timing", Static)
        assert str(timing.render()) == (
            "1200 points x Ts 0.5 s = 10 min of process time\n"
            "LogOn now ends at 10:02:00 (x5, in 2 min)")
        await burst(pilot, "backspace", "backspace", "backspace", "backspace", *"abc")
        assert str(timing.render()) == ""
