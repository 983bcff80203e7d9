"""The window `quadtank --daq CONFIG` / `--par FILE` opens first when it attached to
the caller's running session instead of starting one: those options make a new
session only, so the screen says at once what it attached to and offers the new
session (issue 43: never silently ignored)."""

from __future__ import annotations

from dataclasses import dataclass

from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import Static

from quadtank_tui.ui.widgets.key_button import KeyButton
from quadtank_tui.ui.windows.base import Window


@dataclass(frozen=True)
class AttachedNotice:
    """What the TUI attached to and which of its options it did not apply.

    `session`: the running session's id; `plant`: what it drives ("the simulator
    (Simul)", "the rig of lab.yaml (Active)"); `ignored`: the options as typed
    ("--daq rig.yaml", "--par p.par")."""

    session: str
    plant: str
    ignored: tuple[str, ...]

    def text(self) -> str:
        opts = " and ".join(self.ignored)
        return (f"Attached to your running session {self.session}, whose plant is {self.plant}, "
                f"with the parameters it has now (Setup shows them).\n\n"
                f"{opts} apply to a new session only: they are NOT in force here.\n\n"
                f"n  stop session {self.session} (pumps to 0, its log rows kept) and start a new "
                f"one with {opts}\n"
                f"Enter  keep working in session {self.session}\n\n"
                f"From a shell: quadtank stop {self.session}, then quadtank {' '.join(self.ignored)}")


class AttachedWindow(Window[bool]):
    """Returns True when the user asked for a new session (`n`), False to stay."""

    BINDINGS = [Binding("n", "new_session", "New session"), Binding("enter", "cancel", "Keep this session")]

    def __init__(self, notice: AttachedNotice) -> None:
        super().__init__("Attached to a running session")
        self.notice = notice

    def compose_body(self) -> ComposeResult:
        yield Static(self.notice.text(), id="attached-text", markup=False)

    def compose_buttons(self) -> ComposeResult:
        # Keep first: it has the focus, so an Enter typed ahead never stops a session.
        yield KeyButton("Keep this session", id="cancel", variant="primary")
        yield KeyButton("New session", id="new_session")

    def cancelled(self) -> bool:
        return False

    def action_new_session(self) -> None:
        self.dismiss(True)
