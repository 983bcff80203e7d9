"""Check boxes and radio buttons whose state reads without colour.

Textual draws the mark in both states and tells them apart by colour only; over
SSH, with an unknown colour scheme, a student cannot see which variables will
be logged.  These draw the mark only when on.
"""

from __future__ import annotations

from textual.widgets import Checkbox, RadioButton


class Check(Checkbox):
    """A checkbox: X when on, blank when off."""

    @property
    def BUTTON_INNER(self) -> str:  # type: ignore[override]
        return "X" if self.value else " "


class Switch(Check):
    """A checkbox for an on/off parameter, its label saying which it is."""

    def __init__(self, value: bool = False, **kwargs: object) -> None:
        super().__init__("on" if value else "off", value, **kwargs)  # type: ignore[arg-type]

    def on_checkbox_changed(self, event: Checkbox.Changed) -> None:
        self.label = "on" if event.value else "off"


class Radio(RadioButton):
    """A radio button: a dot when chosen, blank otherwise."""

    @property
    def BUTTON_INNER(self) -> str:  # type: ignore[override]
        return "●" if self.value else " "
