"""The footer of every screen and window: Textual's, its keys styled once.

Textual's Footer makes a FooterKey per binding with the key's `compact` reactive at
its default (True) and binds it to the footer's afterwards, so each key's
`-compact` class changes once it is mounted and the key is styled a second time:
30 restyles when Setup opens, 25 when a window does (about a fifth of the CPU
time a window takes to open).  Here each key is made with the footer's value and
the matching class, so nothing changes when the binding applies it: the same
keys, the same styles, styled once.  (The command palette's key, on screens that
show it, is not bound and keeps its own default, as in Textual's Footer.)

Textual's Footer also rebuilds all its keys whenever its screen's bindings may have
changed: at each focus change (each Tab between a window's fields), each time a
window opens over its screen or closes, each time the screen comes back.  Mostly
they have not: this footer rebuilds only when the keys it would show differ
from those it shows (3 % of the UI tests' CPU time went to those rebuilds).

And Textual's Footer shows no keys until its screen's bindings are first announced,
which comes after the first frame: every screen was drawn, then its footer
rebuilt and drawn again (8 ms of the Main screen's start at 120x40, and a second
frame to the terminal).  This footer makes its keys when it is composed, from the
screen's bindings then; the announcement rebuilds them only if the focus
brought others.
"""

from __future__ import annotations

from typing import Any

from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import Footer
from textual.widgets._footer import FooterKey


class KeyFooter(Footer):
    """A Footer whose keys are made compact or not from the start."""

    #: What the keys shown were made from (`_shown_keys`); None: not made yet.
    _shown: list[tuple[Binding, bool, str]] | None = None

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.set_reactive(Footer._bindings_ready, True)  # the keys in the first frame

    def _shown_keys(self) -> list[tuple[Binding, bool, str]]:
        """Everything Footer.compose makes the keys from: each active binding it
        shows (its key, label, action, group), enabled or not, its tooltip; then
        the command palette's, which it shows at the right when enabled."""
        active = self.screen.active_bindings
        keys = [(b.binding, b.enabled, b.tooltip) for b in active.values() if b.binding.show]
        palette = active.get(self.app.COMMAND_PALETTE_BINDING)
        if self.show_command_palette and self.app.ENABLE_COMMAND_PALETTE and palette is not None:
            keys.append((palette.binding, palette.enabled, palette.tooltip))
        return keys

    def bindings_changed(self, screen: Screen) -> None:
        if (self._shown is not None and self.is_attached and screen is self.screen
                and self._shown_keys() == self._shown):
            return  # the same keys: nothing to rebuild
        super().bindings_changed(screen)

    def compose(self) -> ComposeResult:
        if self._bindings_ready:
            self._shown = self._shown_keys()
        compact = self.compact
        for widget in super().compose():
            # The command palette's key is not bound to the footer: it stays compact.
            if isinstance(widget, FooterKey) and not widget.has_class("-command-palette"):
                widget.set_reactive(FooterKey.compact, compact)
                widget.set_class(compact, "-compact", update=False)
            yield widget
