"""Shown instead of the screens when the terminal is smaller than they can be
drawn in: clipped tanks and cut-off keys would mislead; a sentence does not.

The app pushes it when the terminal shrinks below MIN_SIZE and takes it away when
it grows again; the process runs on meanwhile, and ctrl+q still exits (asking).
Help (F1), the palette (ctrl+p) or the Exit question may open over it: if the
terminal grew meanwhile, it goes as soon as it is back in front.
"""

from __future__ import annotations

from textual.app import ComposeResult
from textual.screen import ModalScreen
from textual.widgets import Static

#: The smallest terminal the screens are laid out for, columns x rows.
MIN_SIZE = (80, 24)


def too_small(width: int, height: int) -> bool:
    return width < MIN_SIZE[0] or height < MIN_SIZE[1]


class TooSmallScreen(ModalScreen[None]):
    """One line: how small the terminal is, and what it needs."""

    DEFAULT_CSS = """
    TooSmallScreen {
        align: center middle;
        background: $background;
    }
    TooSmallScreen Static {
        width: auto;
        max-width: 100%;
        color: $warning;
        text-style: bold;
    }
    """

    def compose(self) -> ComposeResult:
        yield Static(id="too-small")

    def on_mount(self) -> None:
        self.on_resize()

    def on_screen_resume(self) -> None:
        # Back from a window that was over it when the terminal grew (the app's
        # resize check saw that window on top, not this screen): nothing to say.
        if self.app.screen is self and not too_small(*self.app.size):
            self.dismiss()

    def on_resize(self) -> None:
        w, h = self.app.size
        self.query_one("#too-small", Static).update(
            f"terminal too small ({w}x{h}, need {MIN_SIZE[0]}x{MIN_SIZE[1]})")
