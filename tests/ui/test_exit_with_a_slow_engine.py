"""Exit while the engine is slow to answer (a hung DAQ holds the loop for a
timeout or two): the answer that comes after the screen has gone is dropped.

Before, it was delivered to the dead screen from the engine's thread, which raised
`NoMatches: No nodes match 'StatusLine'` (a traceback on the terminal at Exit).
"""

from __future__ import annotations

import logging
import threading
from concurrent.futures import Future
from typing import Any

import pytest
from uikit import Recording, make_app

from quadtank_tui.engine import commands as c
from quadtank_tui.engine.commands import CommandResult


class Slow(Recording):
    """The engine, except that commands stay unanswered until the test answers them."""

    def __init__(self, engine: Any) -> None:
        super().__init__(engine)
        self.waiting: list[Future[CommandResult]] = []

    def submit(self, command: c.Command) -> Future[CommandResult]:
        self.commands.append(command)
        fut: Future[CommandResult] = Future()
        self.waiting.append(fut)
        return fut


async def test_an_answer_after_exit_is_dropped_without_a_traceback(
        engine: Recording, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch) -> None:
    slow = Slow(engine.engine)
    app = make_app(slow)
    crashes: list[BaseException] = []
    monkeypatch.setattr(threading, "excepthook", lambda args: crashes.append(args.exc_value))
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("r")                                 # Run: the answer will be late
        await pilot.pause()
        app.exit()
    assert slow.commands == [c.SetState("Run")]
    with caplog.at_level(logging.ERROR, logger="concurrent.futures"):
        answering = threading.Thread(target=slow.waiting[0].set_result, args=(CommandResult(True, "late"),))
        answering.start()                                      # from the engine's side, as it does
        answering.join(timeout=10)
    assert not answering.is_alive()
    assert crashes == []
    assert [r for r in caplog.records if r.name == "concurrent.futures"] == []
