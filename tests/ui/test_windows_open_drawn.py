"""A live window shows its values as it opens, not at the app's next refresh: its
first drawing ran in on_mount behind an is_mounted guard, which Textual sets only
after on_mount, so the Pump window opened blank (its snapshot test failed every time
on a fast machine; on the others the refresh came first, by timing).  Here the app
refreshes once an hour: what the window shows, it drew itself.  The Setup screen's
tables had the same guard."""

from __future__ import annotations

from contextlib import asynccontextmanager
from typing import AsyncIterator

import pytest
from textual.pilot import Pilot
from textual.widgets import Label, Static
from uikit import Recording

from quadtank_tui.ui.app import build_app
from quadtank_tui.ui.widgets.setup_tables import ProcessTable
from quadtank_tui.ui.windows.logging import LoggingWindow
from quadtank_tui.ui.windows.process import PumpWindow, TankWindow


@asynccontextmanager
async def _opened(engine: Recording, key: str, size: tuple[int, int] = (80, 24)) -> AsyncIterator[Pilot]:
    """The app, refreshing once an hour, with what `key` opens."""
    app = build_app(engine, refresh_interval=3600.0, wall_clock=lambda: 0.0)
    async with app.run_test(size=size) as pilot:
        await pilot.pause()
        await pilot.press(key)
        await pilot.pause()
        yield pilot


@pytest.mark.parametrize("key, window, shows", [
    ("v", PumpWindow, ["Pump 1", "Valve gamma", "0.7", "to tank"]),
    ("h", TankWindow, ["Tank 1", "Tank 4"]),
])
async def test_a_process_window_has_its_table_when_it_opens(engine: Recording, key: str, window: type,
                                                            shows: list[str]) -> None:
    async with _opened(engine, key) as pilot:
        assert isinstance(pilot.app.screen, window)
        text = str(pilot.app.screen.query_one("#table", Static).content)
        assert all(s in text for s in shows), text


async def test_the_logging_window_has_its_state_when_it_opens(engine: Recording) -> None:
    async with _opened(engine, "l") as pilot:
        assert isinstance(pilot.app.screen, LoggingWindow)
        assert str(pilot.app.screen.query_one("#log-state", Label).content).strip()


async def test_a_parameter_table_given_its_parameters_before_it_mounts_shows_them(engine: Recording) -> None:
    """A Setup table whose parameters were set before it was mounted fills itself
    (the Setup screen sets them after, so its own tables do not show this)."""
    from textual.app import App, ComposeResult

    params = engine.snapshot().params

    class One(App[None]):
        def compose(self) -> ComposeResult:
            table = ProcessTable(params, id="process")
            table.set_reactive(ProcessTable.params, params)
            yield table

    app = One()
    async with app.run_test(size=(80, 12)) as pilot:
        await pilot.pause()
        table = app.query_one(ProcessTable)
        assert table.row_count == 4 and "0." in str(table.get_cell("0", "Op.Pt"))
