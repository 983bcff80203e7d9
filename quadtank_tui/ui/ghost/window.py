"""The Ghost window (Main `b`): which saved `.log` to draw behind the trends, and
where its first row goes: at the current log's LogOn, or at a chosen process time.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.content import Content
from textual.containers import Horizontal
from textual.widgets import Input, Label, OptionList, RadioButton, RadioSet, Static
from textual.widgets.option_list import Option

from quadtank_tui.ui.widgets.key_button import KeyButton
from quadtank_tui.ui.windows.base import Window

#: Logs listed, newest first.
MOST_LOGS = 8


@dataclass(frozen=True)
class GhostChoice:
    """The window's answer: the file, and the ghost's first row at LogOn
    (`at` None) or at process time `at`, s."""

    path: Path
    at: float | None = None


class GhostWindow(Window[GhostChoice]):
    """A list of the logs (the newest highlighted), the alignment, Load."""

    BINDINGS = [Binding("enter", "load", "Load")]

    def __init__(self, logs: list[Path], *, at: float | None = None, now: float = 0.0,
                 opener: str | None = None) -> None:
        super().__init__("Ghost run", opener=opener)
        self.logs = logs[:MOST_LOGS]
        self.at, self.now = at, now
        self._initial_at = f"{at if at is not None else now:g}"

    def compose_body(self) -> ComposeResult:
        if self.logs:
            yield OptionList(*(Option(Content(p.name), id=f"log-{n}") for n, p in enumerate(self.logs)), id="ghost-logs")
        else:
            yield Static("No .log in the logs folder yet: save a log first (Main l).", id="no-logs")
        with RadioSet(id="ghost-align"):
            yield RadioButton("First row at the current log's LogOn", value=self.at is None, id="at-logon")
            yield RadioButton("First row at process time", value=self.at is not None, id="at-time")
        with Horizontal(classes="field", id="row-at"):
            yield Label("Time", classes="label")
            yield Input(self._initial_at, id="ghost-at",
                        compact=True, select_on_focus=True)
            yield Label("s", classes="unit")
            yield Static("", classes="error", id="e-at", markup=False)
        yield Label("Typing a time chooses it.  Drawn dimmed behind the live curves; B on Main clears it.",
                    classes="hint")

    def compose_buttons(self) -> ComposeResult:
        yield KeyButton("Load", id="load", variant="primary")
        yield KeyButton("Cancel", id="cancel")

    def on_mount(self) -> None:
        if self.logs:
            ol = self.query_one(OptionList)
            ol.highlighted = 0
            ol.focus()

    @on(Input.Changed, "#ghost-at")
    def _typed_a_time(self, event: Input.Changed) -> None:
        """Typing a time chooses that alignment (no need to visit the buttons)."""
        if event.value.strip() != self._initial_at:
            self.query_one("#at-time", RadioButton).value = True
            self.query_one("#e-at", Static).update("")

    @on(OptionList.OptionSelected)
    @on(Input.Submitted)
    def _enter(self) -> None:
        self.action_load()

    def action_load(self) -> None:
        if not self.logs:
            self.show_message("There is no log to load.")
            return
        highlighted = self.query_one(OptionList).highlighted
        path = self.logs[highlighted or 0]
        if self.query_one("#at-logon", RadioButton).value:
            self.dismiss(GhostChoice(path))
            return
        text = self.query_one("#ghost-at", Input).value.strip()
        try:
            at = float(text)
        except ValueError:
            at = float("nan")
        if not at >= 0.0:
            self.query_one("#e-at", Static).update(f"a process time in s, >= 0; got {text!r}")
            return
        self.dismiss(GhostChoice(path, at))
