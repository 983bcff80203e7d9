"""What every window shares (thesis 5.2; product S6-S7).

* Esc, selecting its opener again (its key, or a click outside the window, where
  the opener is) or clicking its title cancels; Set (Enter) confirms.
* Default puts the default values back into the fields; nothing reaches the
  engine before Set.
* A value that differs from its default is marked (`-modified`: dim italic, as the
  original drew it gray).
* A bad value is named next to its field; the window stays open and the value in
  force is kept.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, ClassVar, Generic, Iterable, TypeVar

from textual import events, on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.content import Content
from textual.reactive import var
from textual.screen import ModalScreen
from textual.widget import Widget
from textual.widgets import Button, Checkbox, Input, Label, Static
from textual.widgets.button import ButtonVariant

from quadtank_tui.core.parameters import Parameters
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.engine.commands import Command, ResetControllers, SetParams
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.values import fmt, parse_number
from quadtank_tui.ui.widgets.check import Switch
from quadtank_tui.ui.widgets.key_button import KeyButton
from quadtank_tui.ui.widgets.key_footer import KeyFooter

T = TypeVar("T")

#: What a parameter window hands back: the commands its Set asks for (possibly
#: none), or None when it was cancelled.
Commands = tuple[Command, ...]


def show_live(widget: Static, text: str) -> bool:
    """Show `text` in a widget a timer updates; whether it changed.

    Static.update repaints even an unchanged text and lays its screen out again
    (the Pump and Logging windows did, at each sample).  So nothing is done when
    the text is the same, and the layout is redone only when the text's lines
    change length (a table's numbers keep their width)."""
    old = widget.content
    if text == old:
        return False
    same_shape = isinstance(old, str) and _shape(widget, old) == _shape(widget, text)
    widget.update(text, layout=not same_shape)
    return True


def _shape(widget: Static, text: str) -> tuple[int, ...]:
    content = Content.from_markup(text) if widget._render_markup else Content(text)
    return tuple(line.cell_length for line in content.split("\n"))


class Window(ModalScreen[T], Generic[T]):
    """A titled modal window with a row of buttons and the closing conventions."""

    DEFAULT_CLASSES = "window"
    BINDINGS = [Binding("escape", "cancel", "Cancel")]

    def __init__(self, title: str, *, opener: str | None = None) -> None:
        super().__init__()
        self.window_title = title
        if opener:
            # The key that opened the window closes it again (when the focus is not
            # in a text field, which takes the key as text).
            self._bindings.bind(opener, "cancel", "Close", show=False)

    def compose(self) -> ComposeResult:
        with Vertical(id="dialog"):
            yield Label(self.window_title, id="title")
            yield from self.compose_body()
            yield Static("", id="message", classes="error", markup=False)
            with Horizontal(id="buttons"):
                yield from self.compose_buttons()
        yield KeyFooter(compact=True)

    def compose_body(self) -> ComposeResult:
        """The window's own content."""
        yield from ()

    @on(events.Mount)
    def _steady_cursor_when_headless(self) -> None:
        # Without a terminal (tests, screenshots) a blinking cursor only makes
        # pictures differ by the time they were taken.
        if self.app.is_headless:
            for field in self.query(Input):
                field.cursor_blink = False

    def compose_buttons(self) -> ComposeResult:
        yield KeyButton("Cancel", id="cancel")

    def cancelled(self) -> T | None:
        """What Cancel returns."""
        return None

    def action_cancel(self) -> None:
        self.dismiss(self.cancelled())

    def show_message(self, text: str) -> None:
        """A message for the whole window (a refused value without a field)."""
        message = self.query_one("#message", Static)
        message.update(text)
        message.display = bool(text)

    async def on_button_pressed(self, event: Button.Pressed) -> None:
        """A button's id names the action it runs ("set", "cancel", "log_on", ...),
        so a button and its key cannot do different things."""
        event.stop()
        if event.button.id:
            await self.run_action(event.button.id)

    def on_click(self, event: events.Click) -> None:
        # A click on the dimmed background is a click where the opener is; a click
        # on the title closes the window too (thesis 5.2).
        if event.widget is self or (event.widget is not None and event.widget.id == "title"):
            self.action_cancel()


class LiveWindow(Window[Commands]):
    """A window that follows the loop: the screen behind it hands it each new
    snapshot (`snapshot`, attributes down) and `show` draws it, from the moment the
    window opens.  Textual's is_mounted turns True only after on_mount, so the first
    drawing is on_mount's (through the watcher, whose guard is for a window being
    taken down, it was skipped, and the Pump, Tanks and Logging windows opened blank
    until the app's next refresh)."""

    # A var, not a reactive: setting a reactive on a screen repaints all of it
    # (the whole terminal, each sample); the watcher updates only what changed.
    snapshot: var[Snapshot | None] = var(None, always_update=True)

    def __init__(self, title: str, snapshot: Snapshot, *, opener: str | None = None) -> None:
        super().__init__(title, opener=opener)
        self.set_reactive(type(self).snapshot, snapshot)

    def on_mount(self) -> None:
        if self.snapshot is not None:
            self.show(self.snapshot)

    def watch_snapshot(self, snapshot: Snapshot | None) -> None:
        if snapshot is not None and self.is_mounted and self.is_attached:
            self.show(snapshot)

    def show(self, snapshot: Snapshot) -> None:
        """Draw `snapshot` in the window's widgets."""
        raise NotImplementedError


def field_row(row_id: str, label: str, field: Widget, unit: str, error_id: str) -> ComposeResult:
    """One row of a window's form: label, the field, its unit, and the line where
    a refused value is named (every editing window lays its fields out so)."""
    with Horizontal(classes="field", id=row_id):
        yield Label(label, classes="label")
        yield field
        yield Label(unit, classes="unit")
        yield Static("", classes="error", id=error_id, markup=False)


def set_default_cancel() -> ComposeResult:
    """The buttons of a window that edits values (their ids are the actions)."""
    yield KeyButton("Set", id="set", variant="primary")
    yield KeyButton("Default", id="default")
    yield KeyButton("Cancel", id="cancel")


@dataclass(frozen=True)
class Field:
    """One editable parameter: its `.par` key, its label, its unit; a flag is a
    switch, `text` a free text the model validates (poles), else a number."""

    key: str
    label: str
    unit: str = ""
    flag: bool = False
    text: bool = False


class ParamWindow(Window[Commands]):
    """Fields for some parameters with Default / Set / Cancel; Set returns a
    SetParams of the changed values, validated together first."""

    BINDINGS = [Binding("enter", "set", "Set"), Binding("ctrl+r", "default", "Default")]

    def __init__(self, title: str, params: Parameters, defaults: Parameters,
                 fields: Iterable[Field], *, opener: str | None = None) -> None:
        super().__init__(title, opener=opener)
        self.params = params
        self.defaults = defaults
        self.fields = tuple(fields)

    # --- layout -------------------------------------------------------------------

    def compose_body(self) -> ComposeResult:
        yield from self.compose_fields(self.fields)

    def compose_fields(self, fields: Iterable[Field]) -> ComposeResult:
        for f in fields:
            i = self.fields.index(f)
            value = self.params.get(f.key)
            field: Widget = Switch(bool(value), id=f"f-{i}", compact=True) if f.flag else \
                Input(fmt(value), id=f"f-{i}", compact=True, select_on_focus=True)
            yield from field_row(f"row-{i}", f.label, field, f.unit, f"e-{i}")

    def compose_buttons(self) -> ComposeResult:
        yield from set_default_cancel()

    def on_mount(self) -> None:
        for i in range(len(self.fields)):
            self._mark(i)

    # --- values -------------------------------------------------------------------

    def field_widget(self, key: str) -> Input | Checkbox:
        i = [f.key for f in self.fields].index(key)
        widget = self.query_one(f"#f-{i}")
        assert isinstance(widget, (Input, Checkbox))  # compose_fields makes nothing else
        return widget

    def _read(self, i: int) -> Any:
        f = self.fields[i]
        w = self.query_one(f"#f-{i}")
        if isinstance(w, Checkbox):
            return w.value
        assert isinstance(w, Input)
        return " ".join(w.value.split()) if f.text else parse_number(f.key, w.value)

    def _mark(self, i: int) -> None:
        """Mark the field modified (dim italic) unless it holds its default."""
        try:
            same = self._read(i) == self.defaults.get(self.fields[i].key)
        except ParameterError:
            same = False
        self.query_one(f"#row-{i}").set_class(not same, "-modified")

    @on(Input.Changed)
    @on(Checkbox.Changed)
    def _changed(self, event: Input.Changed | Checkbox.Changed) -> None:
        wid = event.control.id or ""
        if wid.startswith("f-"):
            i = int(wid[2:])
            self._mark(i)
            self.query_one(f"#e-{i}", Static).update("")
            self.on_field_changed(self.fields[i].key)

    def on_field_changed(self, key: str) -> None:
        """Hook: a field was edited (the General window enables coefficients)."""

    def extra_values(self) -> dict[str, Any]:
        """Hook: values chosen outside the fields (the Setup wave window's wave
        type), validated together with them and set with them."""
        return {}

    def values(self) -> dict[str, Any] | None:
        """The fields' values by key, or None after showing what is wrong."""
        out: dict[str, Any] = self.extra_values()
        bad = False
        for i, f in enumerate(self.fields):
            try:
                out[f.key] = self._read(i)
            except ParameterError as exc:
                self._error(f.key, exc.reason)
                bad = True
        if bad:
            return None
        try:
            self.params.with_values(out)
        except ParameterError as exc:
            self._error(exc.field, exc.reason)
            return None
        return out

    def _error(self, key: str, reason: str) -> None:
        keys = [f.key for f in self.fields]
        if key in keys:
            self.query_one(f"#e-{keys.index(key)}", Static).update(reason)
        else:
            self.show_message(f"{key}: {reason}")

    def changes(self) -> dict[str, Any] | None:
        """Only the values that differ from those in force (None if invalid)."""
        values = self.values()
        if values is None:
            return None
        return {k: v for k, v in values.items() if v != self.params.get(k)}

    def commands(self, changes: dict[str, Any]) -> Commands:
        """What Set sends for these changes."""
        return (SetParams(changes),) if changes else ()

    # --- actions --------------------------------------------------------------------

    def action_set(self) -> None:
        changes = self.changes()
        if changes is not None:
            self.dismiss(self.commands(changes))

    def action_default(self) -> None:
        for i, f in enumerate(self.fields):
            w = self.query_one(f"#f-{i}")
            value = self.defaults.get(f.key)
            if isinstance(w, Checkbox):
                w.value = bool(value)
            else:
                assert isinstance(w, Input)
                w.value = fmt(value)

    @on(Input.Submitted)
    def _submitted(self) -> None:
        self.action_set()


class WholeControllerWindow(ParamWindow):
    """The window of a controller that is the whole loop (state feedback, MPC), not
    one element of the 2x2 matrix: opened like an element's window (1-4), so it takes
    an index it does not need; Reset starts all its states again (ResetControllers()
    with no element: the integrators, the MPC's disturbance estimate and counts)."""

    controller_title: ClassVar[str] = ""
    controller_fields: ClassVar[tuple[Field, ...]] = ()

    def __init__(self, index: int, params: Parameters, defaults: Parameters, *,
                 opener: str | None = None) -> None:
        super().__init__(self.controller_title, params, defaults, self.controller_fields, opener=opener)

    def compose_buttons(self) -> ComposeResult:
        yield from super().compose_buttons()
        yield KeyButton("Reset", id="reset_integrators")

    def action_reset_integrators(self) -> None:
        """The controller's states start again now (the window closes, nothing else changes)."""
        self.dismiss((ResetControllers(),))


#: A window of answers only (no field to type in): the arrows move along its row of
#: buttons, as in any dialog; Tab still does.
ANSWER_ARROWS = [Binding("left", "app.focus_previous", show=False),
                 Binding("right", "app.focus_next", show=False)]


class ConfirmWindow(Window[bool]):
    """A yes/no question (Exit, overwriting a file); Esc answers no."""

    BINDINGS = [Binding("y", "answer(True)", "Yes", show=False),
                Binding("n", "answer(False)", "No", show=False), *ANSWER_ARROWS]

    def __init__(self, title: str, question: str, yes: str = "Yes", no: str = "Cancel") -> None:
        super().__init__(title)
        self.question = question
        self.yes, self.no = yes, no

    def compose_body(self) -> ComposeResult:
        yield Static(self.question, id="question", markup=False)

    def compose_buttons(self) -> ComposeResult:
        yield KeyButton(self.yes, id="yes", variant="error")
        yield KeyButton(self.no, id="cancel")

    def cancelled(self) -> bool:
        return False

    def action_answer(self, yes: bool) -> None:
        self.dismiss(yes)

    def action_yes(self) -> None:
        self.dismiss(True)


@dataclass(frozen=True)
class Choice:
    """One answer of a ChoiceWindow: what it returns, its button text, its colour."""

    answer: str
    label: str
    variant: ButtonVariant = "default"


class ChoiceWindow(Window[str | None]):
    """A question with several answers (Exit with an unsaved log: save, discard or
    cancel); the first answer has the focus, so Enter picks it; Esc answers None.

    Unlike other windows' buttons, these are not named after actions: their ids
    are their positions (choice-0, choice-1, ...), so nothing a user typed (a log
    name in a label) can become an action name."""

    BINDINGS = [*ANSWER_ARROWS]

    def __init__(self, title: str, question: str, choices: Iterable[Choice]) -> None:
        super().__init__(title)
        self.question = question
        self.choices = tuple(choices)

    def compose_body(self) -> ComposeResult:
        yield Static(self.question, id="question", markup=False)

    def compose_buttons(self) -> ComposeResult:
        for n, choice in enumerate(self.choices):
            yield KeyButton(Content(choice.label), id=f"choice-{n}", variant=choice.variant)

    def on_mount(self) -> None:
        self.query_one("#choice-0", Button).focus()

    async def on_button_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        self.dismiss(self.choices[int((event.button.id or "choice-0").removeprefix("choice-"))].answer)


def free_log_name(name: str, exists: Callable[[str], bool]) -> str:
    """`name`, or `name-2`, `name-3`, ... if a log of that name exists: Save at
    Exit never overwrites, and never asks a second question."""
    n = 1
    candidate = name
    while exists(candidate):
        n += 1
        candidate = f"{name}-{n}"
    return candidate
