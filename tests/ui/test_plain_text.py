"""Text from outside the program (a log's rows, a file's name) is
shown as it is, never read as Textual markup: `[/x]` in a toast ended the TUI
with MarkupError, `[b]1` showed a bold 1.

The pilot hides notifications unless asked (`run_test(notifications=True)`): a
terminal shows them, and a toast's text is read as markup only when it renders.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from textual.widgets import SelectionList, Static
from textual.widgets._toast import Toast

from uikit import Recording, make_app
from test_trend_view import write_log

from quadtank_tui.ui.screens.identify import IdentifyScreen


async def toasts(pilot: Any) -> list[str]:
    """The text of every toast on the screen, as it renders."""
    for _ in range(100):
        await pilot.pause(0.02)
        found = list(pilot.app.screen.query(Toast))
        if found:
            return [t.render().plain for t in found]
    raise AssertionError("no toast")


def hostile_row(path: Path) -> None:
    """A log whose sixth row is text a hand (or a broken disk) put there."""
    write_log(path, 10, 0.3, 0.3)
    lines = path.read_text().splitlines(keepends=True)
    lines[-5] = "0.6 0.6 0.3 [/x]\n"
    path.write_text("".join(lines))


async def test_a_ghost_log_with_markup_in_a_row_is_named_not_a_crash(engine: Recording) -> None:
    hostile_row(Path(engine.logs_dir) / "odd.log")
    app = make_app(engine)
    async with app.run_test(size=(120, 40), notifications=True) as pilot:
        await pilot.press("b", "enter")
        shown = await toasts(pilot)
        assert app.is_running and app.screen is app.main
        assert any("odd.log" in s and "'0.6 0.6 0.3 [/x]'" in s for s in shown), shown


async def test_identify_lists_log_names_and_file_errors_as_they_are(engine: Recording) -> None:
    logs = Path(engine.logs_dir)
    hostile_row(logs / "a[b]x.log")
    app = make_app(engine)
    async with app.run_test(size=(120, 40), notifications=True) as pilot:
        await pilot.press("y")
        await pilot.pause()
        assert isinstance(app.screen, IdentifyScreen)
        listed = app.screen.query_one("#logs", SelectionList)
        assert str(listed.get_option_at_index(0).prompt) == "a[b]x.log"
        app.screen._preview(str(logs / "a[b]x.log"))
        status = str(app.screen.query_one("#identify-status", Static).render())
        assert "a[b]x.log" in status and "'0.6 0.6 0.3 [/x]'" in status, status
