"""Esc and a key arriving together (over SSH, one packet) are Esc, then the key.

The bytes go through the parser the terminal driver uses (ui/escape_keys.py) and
its events reach the app in one burst, as the driver hands them over.
"""

from __future__ import annotations

from typing import Any

import pytest
from textual.drivers import linux_driver
from textual.events import Key
from textual.widgets import Input

from uikit import Recording, make_app

from quadtank_tui.engine import commands as c
from quadtank_tui.ui.escape_keys import EscapeThenKeyParser
from quadtank_tui.ui.windows.signals import InputSignalWindow


def keys(data: str) -> list[tuple[str, str | None]]:
    parser = EscapeThenKeyParser()
    events = list(parser.feed(data)) + list(parser.feed(""))
    assert all(isinstance(e, Key) for e in events), events
    return [(e.key, e.character) for e in events if isinstance(e, Key)]


@pytest.mark.parametrize(("data", "expected"), [
    ("\x1br", [("escape", "\x1b"), ("r", "r")]),
    ("\x1bR", [("escape", "\x1b"), ("R", "R")]),
    ("\x1b1", [("escape", "\x1b"), ("1", "1")]),             # Textual: "¡"
    ("\x1b\r", [("escape", "\x1b"), ("enter", "\r")]),       # Textual: a bare Enter
    ("\x1b?", [("escape", "\x1b"), ("question_mark", "?")]),  # Textual: a bare ?
    ("\x1b-", [("escape", "\x1b"), ("minus", "-")]),         # Textual: "–"
    ("\x1b[", [("escape", "\x1b"), ("left_square_bracket", "[")]),
    ("\x1brS", [("escape", "\x1b"), ("r", "r"), ("S", "S")]),
    ("\x1b\x1b", [("escape", "\x1b"), ("escape", "\x1b")]),
    ("\x1bb", [("escape", "\x1b"), ("b", "b")]),   # Textual: ctrl+left (a word jump); b is Ghost
    ("\x1bf", [("escape", "\x1b"), ("f", "f")]),   # Textual: ctrl+right; f is Files on Setup
    # Sequences stay what they are.
    ("\x1b[A", [("up", None)]),
    ("\x1bOP", [("f1", None)]),
])
def test_escape_then_a_key_is_two_keys(data: str, expected: list[tuple[str, str | None]]) -> None:
    assert keys(data) == expected


def test_the_terminal_driver_reads_keys_with_it(engine: Recording) -> None:
    make_app(engine)
    assert linux_driver.XTermParser is EscapeThenKeyParser


async def typed(pilot: Any, data: str) -> None:
    """`data` as the terminal sends it, parsed and handed to the app in one burst."""
    app = pilot.app
    parser = EscapeThenKeyParser()
    for event in [*parser.feed(data), *parser.feed("")]:
        app._driver.send_message(event)
    for _ in range(200):
        await pilot.pause()
        if not app.keys_pending:
            break
    await pilot.pause()


async def test_esc_r_closes_the_window_then_runs(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("i")
        assert isinstance(app.screen, InputSignalWindow)
        await typed(pilot, "\x1br")
        assert app.screen is app.main
        assert engine.snapshot().state == "Run"
        assert engine.sent(c.SetState) == [c.SetState("Run")]


async def test_esc_enter_cancels_and_does_not_set(engine: Recording) -> None:
    """Esc then Enter typed over a changed field: the window is cancelled (Textual
    read a bare Enter: Set)."""
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("i")
        field = app.screen.query_one("#f-0", Input)
        field.value = "0.5"
        await pilot.pause()
        await typed(pilot, "\x1b\r")
        assert app.screen is app.main
    assert engine.sent(c.SetParams) == []
    assert engine.snapshot().params.get("REFERENCE ONE.Mean") != 0.5


async def test_esc_digit_closes_the_window_then_opens_the_element(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("h")
        await typed(pilot, "\x1b1")
        assert type(app.screen).__name__ == "PIDWindow"


async def test_esc_f_closes_the_sampling_window_then_opens_files(setup_app: Any) -> None:
    """ESC f is also what some terminals send for Option+right (a word jump), which
    Textual reads as ctrl+right: the window stayed open with its cursor moved."""
    from uikit import open_setup

    from quadtank_tui.ui.windows.par_files import ParFileWindow
    from quadtank_tui.ui.windows.sampling import SamplingTimeWindow

    async with setup_app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        await pilot.press("s")
        assert isinstance(setup_app.screen, SamplingTimeWindow)
        await typed(pilot, "\x1bf")
        assert isinstance(setup_app.screen, ParFileWindow)
