"""The command palette opens once (issue 18, found by benchmarks/hardening.py's
random keys): ctrl+p, then Help (F1) over it, then ctrl+p again pushed a second
palette and the app ended on `DuplicateIds: '--command-palette'`."""

from __future__ import annotations

from conftest import make_app
from textual.command import CommandPalette


async def test_ctrl_p_under_help_does_not_open_a_second_palette(engine) -> None:  # type: ignore[no-untyped-def]
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        for key in ("ctrl+p", "f1", "ctrl+p"):
            await pilot.press(key)
        await pilot.pause()
        assert app.is_running
        assert sum(isinstance(s, CommandPalette) for s in app.screen_stack) == 1
        for _ in range(3):
            await pilot.press("escape")
        assert app.screen is app.main
