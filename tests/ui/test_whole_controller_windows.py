"""The windows of the controllers that are the whole loop (state feedback, MPC): one
window class gives both their Reset, which starts every state of the controller
again (ResetControllers with no element) and closes the window, nothing else sent."""

from __future__ import annotations

from typing import Any

import pytest
from uikit import make_app

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.engine.commands import ResetControllers, SetParams
from quadtank_tui.ui.screens.main import MainScreen
from quadtank_tui.ui.windows.mpc import MPCWindow
from quadtank_tui.ui.windows.statefb import StateFeedbackWindow


@pytest.mark.parametrize(("family", "window", "title"), [
    ("State feedback", StateFeedbackWindow, "Controller - State feedback"),
    ("MPC", MPCWindow, "Controller - MPC"),
])
async def test_reset_resets_the_whole_controller_and_closes(make_engine: Any, family: str, window: type,
                                                            title: str) -> None:
    engine = make_engine(PRESET.with_values({"CONTROL.Type": family}))
    app = make_app(engine)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("1")
        await pilot.pause()
        assert type(app.screen) is window and app.screen.window_title == title
        sent = len(engine.commands)
        await pilot.click("#reset_integrators")
        await pilot.pause()
        assert isinstance(app.screen, MainScreen)
        assert engine.commands[sent:] == [ResetControllers()]
        assert engine.sent(SetParams) == []
