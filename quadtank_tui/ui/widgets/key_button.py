"""The button of every window: Textual's, except that each Enter presses it.

Textual's Button ignores a press while it still shows the last one (its `-active`
look, 0.2 s): right for a mouse's double click, wrong for keys typed ahead.  Over
SSH a burst such as Enter, Tab, Enter arrives at once, and the app hands the keys
on one after another, as typed (ui/keyorder.py): an Enter on Apply 0.1 s after
the last one was dropped, the Tab moved on to Cancel and the second Enter pressed
that (the design preview's "Apply anyway" then cancelled the design instead).
A click still presses once however fast it is repeated.
"""

from __future__ import annotations

from textual.widgets import Button


class KeyButton(Button):
    """A Button that Enter presses every time."""

    def action_press(self) -> None:
        self.press()
