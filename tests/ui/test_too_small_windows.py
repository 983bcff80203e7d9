"""A terminal below 80x24 shows one sentence (screens/too_small.py); what opens
over that sentence must not leave it behind once the terminal has grown.

Before: F1 (or ctrl+p) on a small terminal, the terminal made larger, Esc: the
sentence "terminal too small (120x40 ...)" stayed on a 120x40 terminal until the
next resize; ctrl+q did nothing there, though the sentence's screen promised it
still exits (asking).
"""

from __future__ import annotations

from typing import Any

import pytest
from uikit import Recording, make_app

from quadtank_tui.ui.screens.help import HelpScreen
from quadtank_tui.ui.screens.too_small import TooSmallScreen
from quadtank_tui.ui.windows.base import ConfirmWindow


async def resize(pilot: Any, width: int, height: int) -> None:
    await pilot.resize_terminal(width, height)
    await pilot.pause()
    await pilot.pause()


@pytest.mark.parametrize(("key", "over"), [("f1", HelpScreen), ("ctrl+q", ConfirmWindow)])
async def test_a_window_over_the_too_small_sentence_leaves_main_once_grown(
        engine: Recording, key: str, over: type) -> None:
    app = make_app(engine)
    async with app.run_test(size=(70, 20)) as pilot:
        await pilot.pause()
        assert isinstance(app.screen, TooSmallScreen)
        await pilot.press(key)
        assert isinstance(app.screen, over)
        await resize(pilot, 120, 40)
        assert isinstance(app.screen, over)  # the window stays where the user is
        await pilot.press("escape")
        await pilot.pause()
        assert app.screen is app.main
        assert not any(isinstance(s, TooSmallScreen) for s in app.screen_stack)


async def test_closed_while_still_small_the_sentence_comes_back(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(70, 20)) as pilot:
        await pilot.pause()
        await pilot.press("f1", "escape")
        await pilot.pause()
        assert isinstance(app.screen, TooSmallScreen)
        await resize(pilot, 80, 24)
        assert app.screen is app.main


async def test_the_sentence_is_shown_once_and_exit_asked_once(engine: Recording) -> None:
    """Found by benchmarks/hardening.py's keys at changing sizes: Help over the
    sentence, the terminal still smaller: a second sentence was pushed over Help;
    Exit asked, Help, a small terminal, ctrl+q: a second Exit question (the
    stack grew to Main, Exit, Help, sentence, Exit, palette, sentence, Help)."""
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        await pilot.press("ctrl+q", "f1")
        await resize(pilot, 70, 20)
        await pilot.press("ctrl+q")  # under Help the Exit question is open already
        await pilot.press("f1")  # Help over the sentence: still readable, clipped
        await resize(pilot, 72, 22)
        kinds = [type(s) for s in app.screen_stack]
        assert kinds.count(TooSmallScreen) == 1 and kinds.count(ConfirmWindow) == 1, kinds
        await resize(pilot, 120, 40)
        for _ in range(3):
            await pilot.press("escape")
            await pilot.pause()
        assert app.screen is app.main, app.screen_stack
