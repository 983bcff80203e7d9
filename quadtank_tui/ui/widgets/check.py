"""Check boxes whose state reads without colour.

Textual draws the mark in both states and tells them apart by colour only; over
SSH, with an unknown colour scheme, a student cannot see which variables will
be logged.  These draw the mark only when on.
"""

from __future__ import annotations

from typing import Any

from textual.binding import Binding
from textual.widgets import Checkbox


class Check(Checkbox):
    """A checkbox: X when on, blank when off."""

    @property
    def BUTTON_INNER(self) -> str:  # type: ignore[override]  # Textual's is a class constant
        return "X" if self.value else " "


class Switch(Check, inherit_bindings=False):
    """A checkbox for an on/off parameter, its label saying which it is.

    Space toggles it; Enter is left to the window, where it means Set.
    """

    BINDINGS = [Binding("space", "toggle_button", "Toggle", show=False)]

    def __init__(self, value: bool = False, **kwargs: Any) -> None:
        super().__init__("on" if value else "off", value, **kwargs)

    def on_checkbox_changed(self, event: Checkbox.Changed) -> None:
        self.label = "on" if event.value else "off"
