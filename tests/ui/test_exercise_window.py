"""The exercise window: `x` on Main opens it; its requirements wait for Automatic,
follow the run, and a finished attempt is summarized (pilot), and its picture."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

from textual.pilot import Pilot
from textual.widgets import Static
from uikit import Recording, make_app

from quadtank_tui.app.exercise import LiveExercise
from quadtank_tui.app.grade import grade_record, load_exercises
from quadtank_tui.engine.commands import SetControlMode, SetParams, SetState
from quadtank_tui.files.exercise import read_exercise
from quadtank_tui.files.par import read_par
from quadtank_tui.ui.app import QuadTankApp
from quadtank_tui.ui.widgets.status_line import StatusLine
from quadtank_tui.ui.windows.exercise import ExerciseWindow

ROOT = Path(__file__).resolve().parents[2]
EXERCISE = ROOT / "params" / "exercises" / "pminus-pi.yaml"


def exercise_app(make_engine: Callable[..., Recording]) -> tuple[QuadTankApp, Recording]:
    """The TUI on the exercise's reference solution, following the exercise; the
    exercise opened at wall time 0 and the window's clock at 100 s."""
    ex = read_exercise(EXERCISE)
    assert ex.reference is not None
    engine = make_engine(read_par(ex.reference).params)
    app = make_app(engine)
    app.exercise = LiveExercise(ex, started=0.0)
    app.exercise_clock = lambda: 100.0  # type: ignore[attr-defined]  # the window's wall clock, fixed
    return app, engine


def the_sample_session(engine: Recording) -> None:
    """As the thesis's appendix A.4 by hand: Run in Manual 600 s, Automatic, +0.1 on r1 at 610 s,
    watched to 1200 s (the exercise's 600 s in Automatic)."""
    engine.submit(SetState("Run"))
    engine.run_for(600.0)
    engine.submit(SetControlMode("Automatic"))
    engine.run_for(10.0)
    mean = engine.snapshot().params.get("REFERENCE ONE.Mean")
    engine.submit(SetParams({"REFERENCE ONE.Mean": mean + 0.1}))
    engine.run_for(590.0)


async def settled(pilot: Pilot, shows: str = "") -> None:
    """Until the window's status line shows `shows` (the screen's refresh timer feeds
    it), then two more refreshes; a deadline reached only when it fails."""
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline:
        await pilot.pause(0.06)
        screen = pilot.app.screen
        status = screen.query("#exercise-status") if isinstance(screen, ExerciseWindow) else None
        if status and shows in str(status.first(Static).content) and \
                (shows or "watched" in str(status.first(Static).content)):
            break
    for _ in range(2):
        await pilot.pause(0.06)


async def test_the_window_waits_follows_summarizes_and_records(make_engine: Callable[..., Recording],
                                                                tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    app, engine = exercise_app(make_engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await settled(pilot)
        assert isinstance(app.screen, ExerciseWindow)  # quadtank exercise opens it first
        await pilot.press("x")  # its key closes it, and opens it again
        assert not isinstance(app.screen, ExerciseWindow)
        await pilot.press("x")
        await settled(pilot)
        table = str(app.screen.query_one("#exercise-requirements", Static).content)
        assert table.count("pending") == 8 and "waits for Automatic" in table
        status = str(app.screen.query_one("#exercise-status", Static).content)
        assert "0 of 600 s watched" in status and "43:20 left" in status
        the_sample_session(engine)
        await settled(pilot, "attempt finished")
        table = str(app.screen.query_one("#exercise-requirements", Static).content)
        assert "5.126 %" in table and "53 s" in table and table.count("[green]met[/]") == 8
        status = str(app.screen.query_one("#exercise-status", Static).content)
        assert "attempt finished: 8 of 8 requirements met: PASSED" in status
        await pilot.press("ctrl+s")
        await pilot.pause()
        message = str(app.screen.query_one("#message", Static).content)
        assert message.startswith("Recorded in records/pminus-pi-"), message
        await pilot.press("p", "m")  # Main's Pause and Manual act with the window open
        await settled(pilot)
        assert engine.snapshot().state == "Pause" and engine.snapshot().control == "Manual"
        assert isinstance(app.screen, ExerciseWindow)
        await pilot.press("l")  # a window Main opens comes on top, and Esc there comes back
        await pilot.pause()
        assert type(app.screen).__name__ == "LoggingWindow"
        await pilot.press("escape")
        await pilot.pause()
        assert isinstance(app.screen, ExerciseWindow)
    (record,) = (tmp_path / "records").iterdir()
    graded = grade_record(record, load_exercises([EXERCISE]))
    figures = {r.name: r.figure for r in graded.requirements}
    assert graded.passed and graded.reproduced == "read"
    assert figures["settling_time 1"] == 53.0 and abs((figures["overshoot 1"] or 0) - 5.126) < 0.01
    assert graded.notes == ["an attempt by hand in the TUI: its figures are read from its log, not run again"]


def test_the_exercise_window_picture(snap_compare, make_engine: Callable[..., Recording]) -> None:
    app, engine = exercise_app(make_engine)

    async def before(pilot: Pilot) -> None:
        await settled(pilot)
        await pilot.press("x")  # closed while the run goes, so that Main behind it is drawn at its end
        engine.submit(SetState("Run"))
        engine.run_for(600.0)
        engine.submit(SetControlMode("Automatic"))
        engine.run_for(10.0)
        engine.submit(SetParams({"REFERENCE ONE.Mean": engine.snapshot().params.get("REFERENCE ONE.Mean") + 0.1}))
        engine.run_for(60.0)  # part of the way: overshoot known, settling pending
        deadline = time.monotonic() + 30.0
        status = app.main.query_one("#status", StatusLine)
        while (status.snapshot is None or status.snapshot.t < 670.0) and time.monotonic() < deadline:
            await pilot.pause(0.06)
        for _ in range(3):
            await pilot.pause(0.06)
        await pilot.press("x")
        await settled(pilot, "70 of 600 s watched")

    assert snap_compare(app, terminal_size=(120, 40), run_before=before)
