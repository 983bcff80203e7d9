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


class Radio(RadioButton):
    """A radio button: a dot when chosen, blank otherwise."""

    @property
    def BUTTON_INNER(self) -> str:  # type: ignore[override]
        return "●" if self.value else " "
