"""The help screen (`?` or F1): every key of Main, Setup and each window, and what
it does, in one scrollable page; Esc (or `?`, F1, q) closes it (F1 is the app's).

The keys are read from the screens' and windows' own bindings (the tooltip is the
long description), so the page cannot drift from what the keys do.  It replaces
Textual's key panel, which squeezed the process image and did not close on Esc.
"""

from __future__ import annotations

from typing import Any, Iterable

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.content import Content
from textual.keys import format_key
from textual.screen import ModalScreen, Screen
from textual.widgets import Static
from rich.table import Table
from rich.text import Text

from quadtank_tui.ui.ghost.window import GhostWindow
from quadtank_tui.ui.windows.base import ConfirmWindow, Window
from quadtank_tui.ui.windows.controller_windows import ControllerTypeWindow, GeneralWindow, PIDWindow
from quadtank_tui.ui.windows.logging import LoggingWindow
from quadtank_tui.ui.windows.par_files import ParFileWindow
from quadtank_tui.ui.windows.pid_extras import PIDExtrasWindow
from quadtank_tui.ui.windows.process import PumpWindow, TankWindow
from quadtank_tui.ui.windows.sampling import SamplingTimeWindow
from quadtank_tui.ui.windows.signals import InputSignalWindow, PlotTypeWindow
from quadtank_tui.ui.windows.tank_setup import TankSetupWindow
from quadtank_tui.ui.windows.wave import WaveWindow

#: Width of the key column, cells.
KEY_WIDTH = 12

#: What every window does alike (ui/windows/base.py).
EVERY_WINDOW = (
    ("enter", "Set: apply the values (a refused one is named next to its field)"),
    ("escape", "Cancel; the key that opened the window closes it too"),
    ("tab", "Next field (shift+tab: previous)"),
    ("ctrl+r", "Put the default values into the fields (where the window has defaults)"),
    ("f1", "This help, over the window"),
)

#: The windows: title, the keys that open them, the class whose bindings it has.
WINDOWS: tuple[tuple[str, str, type[Window[Any]]], ...] = (
    ("Controller type", "Main t, Setup t", ControllerTypeWindow),
    ("PID element", "Main 1-4", PIDWindow),
    ("PID element with extras N, Tr, a, b", "Setup 1-4", PIDExtrasWindow),
    ("General element", "Main or Setup 1-4 (General type)", GeneralWindow),
    ("Input signal", "Main i / I", InputSignalWindow),
    ("Reference wave", "Setup i / I", WaveWindow),
    ("Plot type", "Main g / G", PlotTypeWindow),
    ("Tank (add water in Simul)", "Main h", TankWindow),
    ("Pumps", "Main v", PumpWindow),
    ("Logging", "Main l", LoggingWindow),
    ("Ghost run (a saved .log behind the trends)", "Main b", GhostWindow),
    ("Sampling time", "Setup s", SamplingTimeWindow),
    ("Tank setup", "Setup h, arrows, Enter", TankSetupWindow),
    ("Parameter files", "Setup f", ParFileWindow),
    ("Exit question", "q", ConfirmWindow),
)

#: Keys every window has (EVERY_WINDOW says them once).
_COMMON = {"escape", "enter", "ctrl+r", "tab", "shift+tab"}


_NAMES = {"enter": "Enter", "escape": "Esc", "f1": "F1", "tab": "Tab", "shift+tab": "shift+Tab"}


def key_name(key: str) -> str:
    """A key as printed on the keyboard: "]" for right_square_bracket, "+" for plus."""
    return _NAMES.get(key) or format_key(key)


Row = tuple[str, str]


def row(key: str, text: str) -> Row:
    return key_name(key), text


def table(rows: Iterable[Row], note: str = "") -> Table:
    """Keys and what they do in two columns (a long description wraps in its own)."""
    grid = Table.grid(padding=(0, 2))
    grid.add_column(min_width=KEY_WIDTH, style="bold")
    grid.add_column()
    if note:
        grid.add_row("", Text(note, style="dim"))
    for key, text in rows:
        grid.add_row(key, text)
    return grid


def screen_rows(screen: type[Screen[Any]]) -> list[Row]:
    """One line per key of a screen class (its own bindings, not Textual's)."""
    return [row(b.key, b.tooltip or b.description) for b in _bindings(screen, screen) if b.description]


def window_rows(window: type[Window[Any]]) -> list[Row]:
    """The keys of a window beyond what every window has; numbered choices in one line."""
    rows, choices = [], []
    for binding in _bindings(window, Window):
        if binding.key in _COMMON:
            continue
        if binding.action.startswith(("choose(", "answer(")) and not binding.description:
            choices.append(binding.key)
        elif binding.action.startswith("answer("):
            rows.append(row(binding.key, binding.description))
        elif binding.description:
            rows.append(row(binding.key, binding.tooltip or binding.description))
    if choices:
        rows.insert(0, row(f"{choices[0]}-{choices[-1]}", "Choose that entry (arrows and Enter too)"))
    return rows


def _bindings(node: type[Screen[Any]], base: type[Screen[Any]]) -> Iterable[Binding]:
    """The bindings the classes from `base` down to `node` declare, the most
    derived first (a subclass's key hides its parent's)."""
    seen: set[str] = set()
    for cls in node.__mro__:
        if not (isinstance(cls, type) and issubclass(cls, base)):
            continue
        for binding in cls.__dict__.get("BINDINGS", ()):
            if isinstance(binding, Binding) and binding.key not in seen:
                seen.add(binding.key)
                yield binding


def heading(text: str) -> Static:
    return Static(Content.styled(text, "bold reverse"), classes="help-heading")


class HelpScreen(ModalScreen[None]):
    """Every key, by screen and window."""

    BINDINGS = [
        Binding("escape", "close", "Close"),
        Binding("question_mark", "close", "Close", show=False),
        Binding("q", "close", "Close", show=False),
    ]

    def compose(self) -> ComposeResult:
        from quadtank_tui.ui.screens.main import MainScreen
        from quadtank_tui.ui.screens.setup import SetupScreen

        with VerticalScroll(id="help"):
            yield Static(Content.from_markup(
                "[b]quadtank keys[/]  [dim]arrows / PgUp / PgDn scroll · Esc closes[/]"), id="help-title")
            yield heading(" Main ")
            yield Static(table([
                *screen_rows(MainScreen),
                row("tab", "Reach the input panels: up / down nudge the mean, Enter edits, o on/off"),
                ("click", "A mode word, a controller element, a tank or pump, a trend: its window"),
                ("ctrl+p", "The command palette: every action of the screen, searchable"),
            ]))
            yield heading(" Setup ")
            yield Static(table([*screen_rows(SetupScreen), ("click", "A row of a table or a tank: its window")]))
            yield heading(" Every window ")
            yield Static(table(row(k, t) for k, t in EVERY_WINDOW))
            for title, opened_by, window in WINDOWS:
                yield heading(f" {title} ")
                yield Static(table(window_rows(window), note=f"opened by {opened_by}"))

    def on_mount(self) -> None:
        self.query_one("#help").focus()

    def action_close(self) -> None:
        self.dismiss(None)
