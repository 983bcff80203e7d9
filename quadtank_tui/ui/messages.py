"""Messages the Main screen's widgets post up (attributes down, messages up).

A widget never talks to the engine.  A click on an object (a tank, a controller
element, a channel) asks the screen to run the same action its key runs, so the
mouse and the keyboard cannot drift apart and `check_action` guards both.
"""

from __future__ import annotations

from textual.message import Message


class ActionRequested(Message):
    """Run a screen action, e.g. "element(0)", "tank(3)", "toggle_wave(1)".

    Posted by a widget when the user selects one of its objects with the mouse or
    with the widget's own keys.
    """

    def __init__(self, action: str) -> None:
        super().__init__()
        self.action = action
