"""A live window shows its values as it opens, not at the app's next refresh: its
first drawing ran in on_mount behind an is_mounted guard, which Textual sets only
after on_mount, so the Pump window opened blank (its snapshot test failed every time
on a fast machine; on the others the refresh came first, by timing).  Here the app
refreshes once an hour: what the window shows, it drew itself."""

from __future__ import annotations

import pytest
from textual.widgets import Label, Static
from uikit import Recording

from quadtank_tui.ui.app import build_app
from quadtank_tui.ui.widgets.setup_tables import ProcessTable
from quadtank_tui.ui.windows.logging import LoggingWindow
from quadtank_tui.ui.windows.process import PumpWindow, TankWindow


@pytest.mark.parametrize("key, window, shows", [
    ("v", PumpWindow, ["Pump 1", "Valve gamma", "0.7", "to tank"]),
    ("h", TankWindow, ["Tank 1", "Tank 4"]),
])
async def test_a_process_window_has_its_table_when_it_opens(engine: Recording, key: str, window: type,
                                                            shows: list[str]) -> None:
    app = build_app(engine, refresh_interval=3600.0, wall_clock=lambda: 0.0)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.pause()
        await pilot.press(key)
        await pilot.pause()
        assert isinstance(app.screen, window)
        text = str(app.screen.query_one("#table", Static).content)
        assert all(s in text for s in shows), text


async def test_the_logging_window_has_its_state_when_it_opens(engine: Recording) -> None:
    app = build_app(engine, refresh_interval=3600.0, wall_clock=lambda: 0.0)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.pause()
        await pilot.press("l")
        await pilot.pause()
        assert isinstance(app.screen, LoggingWindow)
        assert str(app.screen.query_one("#log-state", Label).content).strip()


async def test_the_setup_tables_are_filled_when_they_open(engine: Recording) -> None:
    app = build_app(engine, refresh_interval=3600.0, wall_clock=lambda: 0.0)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        await pilot.press("S")
        await pilot.pause()
        table = app.screen.query_one(ProcessTable)
        assert table.row_count == 4 and "0." in str(table.get_cell("0", "Op.Pt"))
