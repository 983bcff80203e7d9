"""A window's buttons are readable, focused or not: the colours drawn for each
label (Textual's focus reverses them) are at least 4.5:1 apart (WCAG AA for text).
Textual's error variant, focused, drew pale pink on light pink: the Exit window's
"Stop the loop and exit" and "Stop the session" (ui/styles/windows.tcss)."""

from __future__ import annotations

import pytest
from rich.segment import Segment
from textual.geometry import Region
from uikit import Recording, make_app

from quadtank_tui.ui.widgets.key_button import KeyButton
from quadtank_tui.ui.widgets.trend_style import contrast

#: WCAG 2's least contrast for ordinary text.
AA = 4.5


def _label_colours(button: KeyButton) -> set[tuple[tuple[int, int, int], tuple[int, int, int]]]:
    """(text, background) of each drawn character of the label, reverse applied."""
    strip = button.render_lines(Region(0, 0, button.size.width, 1))[0]
    pairs = set()
    for segment in strip:
        assert isinstance(segment, Segment)
        style = segment.style
        if not segment.text.strip() or style is None or style.color is None or style.bgcolor is None:
            continue
        fg, bg = style.color.get_truecolor(), style.bgcolor.get_truecolor()
        if style.reverse:
            fg, bg = bg, fg
        pairs.add((tuple(fg), tuple(bg)))
    return pairs  # type: ignore[return-value]


@pytest.mark.parametrize("focused", ["yes", "cancel"])
async def test_the_exit_windows_buttons_are_readable_focused_or_not(engine: Recording, focused: str) -> None:
    app = make_app(engine)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("q")
        await pilot.pause()
        buttons = list(app.screen.query(KeyButton))
        assert {b.id for b in buttons} >= {"yes", "cancel"} and app.screen.query_one("#yes", KeyButton).variant == "error"
        app.screen.query_one(f"#{focused}").focus()
        await pilot.pause()
        for button in buttons:
            pairs = _label_colours(button)
            assert pairs, button.id
            worst = min(contrast(fg, bg) for fg, bg in pairs)
            assert worst >= AA, f"{button.id} ({'focused' if button.has_focus else 'not focused'}): {worst:.2f}:1"
