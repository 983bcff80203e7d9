"""The Logging window (thesis Figure 36; M8).

Points, file name and variables are parameters (LOGGING.*), set with the usual
Default / Set / Cancel.  LogOn, LogOff and Save act at once, like the original's
buttons, through the `submit` the screen hands in; the window stays open and its
progress bar follows the snapshots the screen passes down.  Save asks before it
overwrites an existing file.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any, Callable

from textual import on, work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.widgets import Button, Checkbox, Input, Label, ProgressBar, Static

from quadtank_tui.core.parameters import POINTS_MAX, Parameters
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.engine.commands import Command, LogDiscard, LogOff, LogOn, LogSave, SetParams
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.files.names import LOG_VARIABLES, check_file_name
from quadtank_tui.ui.labels import log_state
from quadtank_tui.ui.log_timing import log_timing
from quadtank_tui.ui.values import fmt, parse_number
from quadtank_tui.ui.widgets.check import Check
from quadtank_tui.ui.widgets.key_button import KeyButton
from quadtank_tui.ui.windows.base import (
    Choice, ChoiceWindow, ConfirmWindow, LiveWindow, free_log_name, show_live,
)

_POINTS, _FILE, _VARS = "LOGGING.Points", "LOGGING.LogFile", "LOGGING.Variables"
#: Longest log name: the file system's 255 bytes, less `.log.partial` and room for
#: the `-recovered-N` a kept log gets.
MAX_NAME = 200


def name_problem(name: str) -> str | None:
    """Why `name` cannot be a log's name (None if it can), checked before the
    file system is asked anything about it."""
    if len(name) > MAX_NAME:
        return f"too long: {len(name)} characters, at most {MAX_NAME}"
    try:
        check_file_name(name, _FILE)
    except ParameterError as exc:
        return exc.reason
    return None


class LoggingWindow(LiveWindow):
    """Set up, start, stop and save a log."""

    BINDINGS = [
        Binding("ctrl+o", "log_on", "LogOn"),
        Binding("ctrl+b", "log_off", "LogOff"),
        Binding("ctrl+s", "save", "Save"),
        Binding("ctrl+r", "default", "Default"),
    ]

    def __init__(self, snapshot: Snapshot, defaults: Parameters, *,
                 submit: Callable[[Command], Any], log_exists: Callable[[str], bool],
                 opener: str | None = None, now: Callable[[], datetime] = datetime.now) -> None:
        super().__init__("Logging", snapshot, opener=opener)
        self.params = snapshot.params
        self.defaults = defaults
        self.submit = submit
        self.log_exists = log_exists
        self.now = now  # the wall clock the end of the log is told in

    def compose_body(self) -> ComposeResult:
        p = self.params
        with Horizontal(classes="field", id="row-points"):
            yield Label("Points", classes="label")
            yield Input(fmt(p.get(_POINTS)), id="points", compact=True, select_on_focus=True)
            yield Label(f"1..{POINTS_MAX}", classes="unit")
            yield Static("", classes="error", id="points-error", markup=False)
        yield Static("", id="log-timing", classes="hint", markup=False)
        with Horizontal(classes="field", id="row-file"):
            yield Label("File", classes="label")
            yield Input(p.get(_FILE), id="file", compact=True, select_on_focus=True)
            yield Label(".log", classes="unit")
            yield Static("", classes="error", id="file-error", markup=False)
        chosen = p.get(_VARS)
        half = (len(LOG_VARIABLES) + 1) // 2
        for row, names in enumerate((LOG_VARIABLES[:half], LOG_VARIABLES[half:])):
            with Horizontal(classes="field vars", id=f"row-vars-{row}"):
                yield Label("Variables" if row == 0 else "", classes="label")
                for name in names:
                    yield Check(name, value=name in chosen, id=f"var-{name}", compact=True)
        yield Static("", classes="error", id="vars-error", markup=False)
        with Horizontal(id="progress-row"):
            yield ProgressBar(total=100, show_eta=False, id="progress")
            yield Label("", id="log-state", markup=False)

    def compose_buttons(self) -> ComposeResult:
        yield KeyButton("LogOn", id="log_on", variant="success")
        yield KeyButton("LogOff", id="log_off", variant="warning")
        yield KeyButton("Save", id="save")
        yield KeyButton("Set", id="set", variant="primary")
        yield KeyButton("Default", id="default")
        yield KeyButton("Cancel", id="cancel")

    def on_mount(self) -> None:
        self._mark_all()
        self._warn_if_exists()

    # --- the live part ------------------------------------------------------------

    def show(self, snapshot: Snapshot) -> None:
        log = snapshot.log
        self.query_one(ProgressBar).update(progress=round(100 * log.progress, 1))
        show_live(self.query_one("#log-state", Label), log_state(log))
        self.query_one("#log_on", Button).disabled = log.active
        self.query_one("#log_off", Button).disabled = not log.active
        self.query_one("#save", Button).disabled = not log.unsaved
        self._show_timing()

    def _show_timing(self) -> None:
        """How long the Points in the field take, and when the log ends."""
        if self.snapshot is None:
            return
        try:
            points: int | None = int(parse_number(_POINTS, self.query_one("#points", Input).value))
        except ParameterError:
            points = None
        show_live(self.query_one("#log-timing", Static), log_timing(points, self.snapshot, self.now()))

    # --- the settings -------------------------------------------------------------

    def _variables(self) -> tuple[str, ...]:
        return tuple(n for n in LOG_VARIABLES if self.query_one(f"#var-{n}", Checkbox).value)

    def values(self) -> dict[str, Any] | None:
        """The settings in the fields, validated together; None after showing why not."""
        try:
            points = parse_number(_POINTS, self.query_one("#points", Input).value)
        except ParameterError as exc:
            self.query_one("#points-error", Static).update(exc.reason)
            return None
        name = self.query_one("#file", Input).value.strip()
        problem = name_problem(name)
        if problem is not None:
            self.query_one("#file-error", Static).update(problem)
            return None
        out = {_POINTS: points, _FILE: name, _VARS: self._variables()}
        try:
            self.params.with_values(out)
        except ParameterError as exc:
            where = {_POINTS: "#points-error", _FILE: "#file-error"}.get(exc.field, "#vars-error")
            self.query_one(where, Static).update(exc.reason)
            return None
        return out

    def changes(self) -> dict[str, Any] | None:
        values = self.values()
        if values is None:
            return None
        return {k: v for k, v in values.items() if v != self.params.get(k)}

    def _mark_all(self) -> None:
        d = self.defaults
        try:
            points_same = parse_number(_POINTS, self.query_one("#points", Input).value) == d.get(_POINTS)
        except ParameterError:
            points_same = False
        self.query_one("#row-points").set_class(not points_same, "-modified")
        self.query_one("#row-file").set_class(
            self.query_one("#file", Input).value.strip() != d.get(_FILE), "-modified")
        for row in self.query(".vars"):
            row.set_class(self._variables() != d.get(_VARS), "-modified")

    @on(Input.Changed)
    @on(Checkbox.Changed)
    def _changed(self) -> None:
        for wid in ("#points-error", "#file-error", "#vars-error"):
            self.query_one(wid, Static).update("")
        self._mark_all()
        self._warn_if_exists()
        self._show_timing()

    def _warn_if_exists(self) -> None:
        """Say at once what is wrong with the name, or that Save will ask."""
        name = self.query_one("#file", Input).value.strip()
        if not name:
            return
        problem = name_problem(name)
        if problem is not None:
            self.query_one("#file-error", Static).update(problem)
        elif self.log_exists(name):
            self.query_one("#file-error", Static).update("exists: Save asks before overwriting")

    # --- actions --------------------------------------------------------------------

    def action_set(self) -> None:
        changes = self.changes()
        if changes is not None:
            self.dismiss((SetParams(changes),) if changes else ())

    def action_default(self) -> None:
        d = self.defaults
        self.query_one("#points", Input).value = fmt(d.get(_POINTS))
        self.query_one("#file", Input).value = d.get(_FILE)
        for n in LOG_VARIABLES:
            self.query_one(f"#var-{n}", Checkbox).value = n in d.get(_VARS)

    @work
    async def action_log_on(self) -> None:
        """Apply the settings in the fields, then start logging with them; an
        unsaved log is saved (the default) or discarded first, as the user says."""
        changes = self.changes()
        if changes is None:
            return
        log = self.snapshot.log if self.snapshot is not None else None
        if log is not None and log.unsaved:
            earlier = log.started_as or log.file
            name = free_log_name(earlier, self.log_exists)
            answer = await self.app.push_screen_wait(ChoiceWindow(
                "LogOn", f"The log ({log.rows} rows) has not been saved.\n"
                f"Save then LogOn saves it as logs/{name}.log first.",
                (Choice("save", "Save then LogOn", "success"),
                 Choice("discard", "Discard then LogOn", "error"),
                 Choice("cancel", "Cancel"))))
            if answer == "save":
                self.submit(LogSave(name))
            elif answer == "discard":
                self.submit(LogDiscard())
            else:
                return
        if changes:
            self.submit(SetParams(changes))
            self.params = self.params.with_values(changes)
        self.submit(LogOn())

    def action_log_off(self) -> None:
        self.submit(LogOff())

    @work
    async def action_save(self) -> None:
        """Save under the name in the field; ask first if that file exists."""
        name = self.query_one("#file", Input).value.strip()
        problem = name_problem(name)
        if problem is not None:
            self.query_one("#file-error", Static).update(problem)
            return
        overwrite = False
        if self.log_exists(name):
            question = f"logs/{name}.log exists. Overwrite it?"
            overwrite = await self.app.push_screen_wait(
                ConfirmWindow("Save log", question, yes="Overwrite"))
            if not overwrite:
                return
        self.submit(LogSave(name, overwrite=overwrite))

    @on(Input.Submitted)
    def _submitted(self) -> None:
        self.action_set()
