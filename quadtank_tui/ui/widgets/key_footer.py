"""The footer of every screen and window: Textual's, its keys styled once.

Textual's Footer makes a FooterKey per binding with the key's `compact` reactive at
its default (True) and binds it to the footer's afterwards, so each key's
`-compact` class changes once it is mounted and the key is styled a second time:
30 restyles when Setup opens, 25 when a window does (about a fifth of the CPU
time a window takes to open).  Here each key is made with the footer's value and
the matching class, so nothing changes when the binding applies it: the same
keys, the same styles, styled once.  (The command palette's key, on screens that
show it, is not bound and keeps its own default, as in Textual's Footer.)
"""

from __future__ import annotations

from textual.app import ComposeResult
from textual.widgets import Footer
from textual.widgets._footer import FooterKey


class KeyFooter(Footer):
    """A Footer whose keys are made compact or not from the start."""

    def compose(self) -> ComposeResult:
        compact = self.compact
        for widget in super().compose():
            # The command palette's key is not bound to the footer: it stays compact.
            if isinstance(widget, FooterKey) and not widget.has_class("-command-palette"):
                widget.set_reactive(FooterKey.compact, compact)
                widget.set_class(compact, "-compact", update=False)
            yield widget
