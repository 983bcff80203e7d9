"""The Parameters window (thesis 5.4, Figure 40; S5): load or save every parameter
by name in `params/` (`.par` is added).

`default` and `preset` are reserved: they load the defaults file and the built-in
values.  `preset` is never written; `default.par`, everyone's defaults, only by an
administrator of the lab (session.roles: a group the lab file names, or write
access to the defaults), after asking; anyone else is told who may.  Saving over an
existing file asks first.  The
window only decides what to ask for; the screen sends it, and when the engine
refuses a file (a broken line, a value out of range) the screen opens the window
again with the engine's message, which names the file, the line and the key, and
the parameters in use stay as they were.
"""

from __future__ import annotations

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.content import Content
from textual.widgets import Input, Label, OptionList, Static
from textual.widgets.option_list import Option

from quadtank_tui.files.names import check_file_name
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.engine.commands import LoadPar, SavePar
from quadtank_tui.files.par import RESERVED, SUFFIX
from quadtank_tui.ui.widgets.key_button import KeyButton
from quadtank_tui.ui.windows.base import Commands, ConfirmWindow, Window

#: What the reserved names stand for, shown in the list.
RESERVED_NOTES = {"default": "the defaults (admins save)", "preset": "the built-in values (load only)"}


def why_not_administrator(what: str) -> str | None:
    """None if this user administers the lab; else the reason, naming who may."""
    from quadtank_tui.session import roles
    from quadtank_tui.session.lab import LabConfigError, load_lab_config

    try:
        roles.require_administrator(roles.current_user().uid, load_lab_config(), what)
    except (LabConfigError, roles.NotPermitted) as exc:
        return str(exc)
    return None


def stem(name: str) -> str:
    """The name as typed, without surrounding blanks and a `.par` the user added."""
    name = name.strip()
    return name[: -len(SUFFIX)] if name.lower().endswith(SUFFIX) else name


class ParFileWindow(Window[Commands]):
    """Name field, the list of saved settings, Load / Save / Cancel."""

    BINDINGS = [Binding("ctrl+l", "load", "Load"), Binding("ctrl+s", "save", "Save")]

    def __init__(self, names: list[str], *, name: str = "", error: str = "",
                 opener: str | None = None) -> None:
        super().__init__("Parameter files", opener=opener)
        self.names = sorted(set(names) | set(RESERVED_NOTES))
        self.initial_name = name
        self.error = error

    def compose_body(self) -> ComposeResult:
        with Horizontal(classes="field"):
            yield Label("Name", classes="label")
            yield Input(self.initial_name, id="name", compact=True, placeholder="e.g. mysetting")
            yield Label(SUFFIX, classes="unit")
        yield OptionList(*(Option(Content(self._entry(n)), id=n) for n in self.names), id="files")
        yield Static(self.error, id="par-error", classes="error", markup=False)

    def compose_buttons(self) -> ComposeResult:
        yield KeyButton("Load", id="load", variant="primary")
        yield KeyButton("Save", id="save")
        yield KeyButton("Cancel", id="cancel")

    def _entry(self, name: str) -> str:
        note = RESERVED_NOTES.get(name)
        return f"{name:<16} {note}" if note else name

    def on_mount(self) -> None:
        self.query_one("#name", Input).focus()
        self.query_one("#par-error").display = bool(self.error)
        if self.initial_name in self.names:
            self.query_one(OptionList).highlighted = self.names.index(self.initial_name)

    # --- helpers ----------------------------------------------------------------------------

    def say(self, text: str) -> None:
        """Show why a request was refused (empty text hides the line)."""
        line = self.query_one("#par-error", Static)
        line.update(text)
        line.display = bool(text)

    def chosen(self) -> str | None:
        """The typed name if it is a usable file name; None after saying why."""
        name = stem(self.query_one("#name", Input).value)
        if not name:
            self.say("Type a name or choose one from the list.")
            return None
        try:
            return check_file_name(name, "name")
        except ParameterError as exc:
            self.say(f"'{name}': {exc.reason.replace('must be', 'a parameter file name must be')}")
            return None

    # --- actions ------------------------------------------------------------------------------

    def action_load(self) -> None:
        name = self.chosen()
        if name is not None:
            self.dismiss((LoadPar(name),))

    def action_save(self) -> None:
        name = self.chosen()
        if name is None:
            return
        if name.lower() == "default":
            self._save_defaults()
            return
        if name.lower() in RESERVED:
            self.say(f"Not saved: {RESERVED[name.lower()]}.")
            return
        if name not in self.names:
            self.dismiss((SavePar(name),))
            return

        def answered(yes: bool | None) -> None:
            if yes:
                self.dismiss((SavePar(name, overwrite=True),))
            else:
                self.say(f"Not saved: {name}{SUFFIX} is kept as it was.")

        self.app.push_screen(
            ConfirmWindow("Overwrite?", f"params/{name}{SUFFIX} exists. Replace it with the parameters in use?",
                          yes="Overwrite"),
            answered,
        )

    def _save_defaults(self) -> None:
        why = why_not_administrator("saving default.par")
        if why is not None:
            self.say(f"Not saved: {why}.")
            return

        def answered(yes: bool | None) -> None:
            if yes:
                self.dismiss((SavePar("default", overwrite=True, defaults=True),))
            else:
                self.say(f"Not saved: default{SUFFIX} is kept as it was.")

        self.app.push_screen(
            ConfirmWindow("Replace the defaults?", f"default{SUFFIX} holds the defaults every user starts "
                          "with. Replace it with the parameters in use?", yes="Replace"),
            answered,
        )

    @on(OptionList.OptionHighlighted, "#files")
    def _highlighted(self, event: OptionList.OptionHighlighted) -> None:
        # Only the user's browsing fills the name, not the list's own first highlight.
        if event.option.id is not None and event.option_list.has_focus:
            self.query_one("#name", Input).value = event.option.id

    @on(OptionList.OptionSelected, "#files")
    def _selected(self, event: OptionList.OptionSelected) -> None:
        if event.option.id is not None:
            self.query_one("#name", Input).value = event.option.id
            self.action_load()

    @on(Input.Changed, "#name")
    def _typed(self, event: Input.Changed) -> None:
        if event.value != self.initial_name:  # not the name the message is about
            self.say("")

    @on(Input.Submitted, "#name")
    def _submitted(self) -> None:
        self.action_load()
