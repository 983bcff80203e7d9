"""Each Enter on a window's button presses it, however soon after the last press
(ui/widgets/key_button.py): a burst typed over SSH loses no key."""

from __future__ import annotations

import re
from pathlib import Path

from textual.app import App, ComposeResult
from textual.widgets import Button

import quadtank_tui.ui
from quadtank_tui.ui.widgets.key_button import KeyButton


class _Presses(App[None]):
    def __init__(self, button: Button) -> None:
        super().__init__()
        self.button = button
        self.pressed = 0

    def compose(self) -> ComposeResult:
        yield self.button

    def on_button_pressed(self) -> None:
        self.pressed += 1


def _slow_to_show(button: Button) -> Button:
    """Its pressed look kept 30 s instead of 0.2 s: every key or click of the test
    comes while it shows, however loaded the machine."""
    button.active_effect_duration = 30.0
    return button


async def _pressed(button: Button, *keys: str) -> int:
    app = _Presses(_slow_to_show(button))
    async with app.run_test() as pilot:
        button.focus()
        await pilot.press(*keys)
        await pilot.pause()
        return app.pressed


async def test_every_enter_in_a_burst_presses() -> None:
    assert await _pressed(KeyButton("Apply"), "enter", "enter", "enter") == 3
    # Textual's own button drops the keys that come while it shows the last press.
    assert await _pressed(Button("Apply"), "enter", "enter", "enter") == 1


async def test_a_click_repeated_at_once_still_presses_once() -> None:
    app = _Presses(_slow_to_show(KeyButton("Apply")))
    async with app.run_test() as pilot:
        await pilot.click(KeyButton)
        await pilot.click(KeyButton)
        await pilot.pause()
        assert app.pressed == 1


def test_the_interface_makes_its_buttons_as_key_buttons() -> None:
    """A window added later with Textual's Button would drop keys again."""
    made = {str(path.relative_to(Path(quadtank_tui.ui.__file__).parent)): len(found)
            for path in Path(quadtank_tui.ui.__file__).parent.rglob("*.py")
            if (found := re.findall(r"(?<![\w.])Button\(", path.read_text()))}
    assert made == {}
