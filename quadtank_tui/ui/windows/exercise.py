"""The exercise window (issue 45; docs/exercises.md): the exercise's text, each
requirement with its state now (pending, met, missed) and figure, the time left,
and a finished attempt's summary.

It follows the loop as the other live windows do: the Main screen hands it each
snapshot, and it reads the history since the attempt began (the switch to
Automatic) from the engine.  The figures are app/exercise.py's LiveExercise, the
same code `quadtank run --exercise` and `quadtank grade` judge with.  It sits at
the right edge so that the process image and the trends stay in view.
"""

from __future__ import annotations

import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable

from textual import events
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.css.query import NoMatches
from textual.widgets import Static

from quadtank_tui.app.exercise import LiveExercise, LiveState
from quadtank_tui.engine.handle import EngineHandle
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.widgets.key_button import KeyButton
from quadtank_tui.ui.windows.base import LiveWindow, show_live

#: How a state is written (colour by markup; the word itself says it without colour).
STATES = {"pending": "[dim]pending[/]", "met": "[green]met[/]", "missed": "[b red]MISSED[/]"}


def clock(seconds: float | None) -> str:
    """`44:12` (minutes and seconds); negative: over the time."""
    if seconds is None:
        return "no time limit"
    sign = "-" if seconds < 0 else ""
    s = int(abs(seconds))
    return f"{sign}{s // 60}:{s % 60:02d} left" if not sign else f"time is up ({sign}{s // 60}:{s % 60:02d})"


def requirement_table(state: LiveState) -> str:
    """The requirements as rows of fixed columns (markup for the states)."""
    width = max([len(r.name) for r in state.rows] + [11])
    lines = [f"[b]{'requirement':<{width}}  {'limit':<12} {'now':>12}  state[/]"]
    for r in state.rows:
        lines.append(f"{r.name:<{width}}  {r.limit:<12} {r.figure:>12}  {STATES[r.state]}")
        if r.detail and r.state != "met":
            lines.append(f"[dim]{'':<{width}}  {escape(r.detail)}[/]")
    return "\n".join(lines)


def reflowed(text: str) -> str:
    """The exercise's text with its paragraphs (blank-line separated) as single lines,
    so the window wraps them at its own width, not at the file's."""
    paragraphs = [" ".join(p.split()) for p in text.strip().split("\n\n")]
    return "\n\n".join(p for p in paragraphs if p)


def escape(text: str) -> str:
    return text.replace("[", r"\[")


class ExerciseWindow(LiveWindow):
    """The exercise and its requirements, live."""

    #: the Main screen hands it each snapshot (screens/main.py _feed_live)
    follows_loop = True

    BINDINGS = [Binding("ctrl+s", "record", "Record")]

    #: where the records of attempts by hand go (a folder of the working directory)
    RECORDS = Path("records")

    #: The window's own keys; every other key the Main screen binds acts with the window
    #: open (the student runs the attempt while reading it; a window it opens comes on top).
    OWN = ("escape", "x", "ctrl+s")

    async def on_key(self, event: events.Key) -> None:
        if event.key in self.OWN:
            return
        main = getattr(self.app, "main", None)
        binding = next((b for b in getattr(type(main), "BINDINGS", ()) if getattr(b, "key", None) == event.key), None)
        if main is None or binding is None:
            return
        event.stop()
        event.prevent_default()
        await main.run_action(binding.action)

    def __init__(self, snapshot: Snapshot, tracker: LiveExercise, engine: EngineHandle, *,
                 opener: str | None = None, wall_clock: Callable[[], float] = time.time) -> None:
        super().__init__(f"Exercise: {tracker.exercise.title}", snapshot, opener=opener)
        self.tracker = tracker
        self.engine = engine
        self.wall_clock = wall_clock

    def compose_buttons(self) -> ComposeResult:
        yield KeyButton("Record", id="record")
        yield KeyButton("Close", id="cancel")

    def compose_body(self) -> ComposeResult:
        ex = self.tracker.exercise
        with VerticalScroll(id="exercise-body"):
            yield Static(escape(reflowed(ex.text)), id="exercise-text")
            yield Static("", id="exercise-requirements")
        yield Static("", id="exercise-status")

    def action_record(self) -> None:
        """Write the finished attempt's record (records/EXERCISE-USER-TIME/) for quadtank grade."""
        from quadtank_tui.app.exercise import ExerciseRefused
        from quadtank_tui.files.record import os_user

        snap = self.snapshot
        state = self.tracker.state(self.engine.history(), snap.params, self.wall_clock()) if snap else None
        if snap is None or state is None or not state.finished:
            self.show_message("The attempt is not finished yet: it is recorded once it has run its time in Automatic")
            return
        now = datetime.fromtimestamp(self.wall_clock(), timezone.utc)
        folder = self.RECORDS / f"{self.tracker.exercise.id}-{os_user()['name']}-{now:%Y%m%d-%H%M%S}"
        try:
            written = self.tracker.record(self.engine.history(), snap.params, folder, now=now,
                                          rig=snap.operation == "Active", backend=snap.backend)
        except (ExerciseRefused, OSError, ValueError) as exc:
            self.show_message(f"Not recorded: {exc}")
            return
        self.show_message(f"Recorded in {written}/ (quadtank grade {written})")

    def show(self, snapshot: Snapshot) -> None:
        self.tracker.note(snapshot.automatic_since)
        state = self.tracker.state(self.engine.history(), snapshot.params, self.wall_clock())
        where = "rig" if snapshot.operation == "Active" else "simulator"
        status = f"{state.summary()}\n{clock(state.time_left)}   on the {where}"
        try:
            show_live(self.query_one("#exercise-requirements", Static), requirement_table(state))
            show_live(self.query_one("#exercise-status", Static), status)
        except NoMatches:  # not composed yet, or being taken down: the next snapshot draws it
            pass
