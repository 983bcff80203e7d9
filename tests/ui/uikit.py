"""Helpers the UI tests import (conftest.py holds the fixtures): the app on the real
engine with a manual clock, and the engine remembering what the UI sent it.

A name of its own, like tests/session/sessionkit.py and tests/daq/daqkit.py:
pytest's importlib mode does not put the test folder on sys.path (conftest.py
does) and every folder has a `conftest` module, so `from uikit import ...`
found whichever folder's conftest was imported first.
"""

from __future__ import annotations

import time
from datetime import datetime
from pathlib import Path
from typing import Any

from rich.text import Text
from textual._compositor import CompositorUpdate
from textual.widget import Widget
from textual.worker import WorkerCancelled

from quadtank_tui.core.parameters import Parameters
from quadtank_tui.engine.commands import Command
from quadtank_tui.engine.runner import Engine, build_engine
from quadtank_tui.files.par import format_par
from quadtank_tui.ui.app import QuadTankApp, build_app

EPOCH = datetime(2026, 1, 5, 9, 0, 0)


class Recording:
    """The engine, remembering every command the UI sent it (what a test checks
    is what reached the engine)."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        self.commands: list[Command] = []

    def submit(self, command: Command) -> Any:
        self.commands.append(command)
        return self.engine.submit(command)

    def sent(self, kind: type) -> list[Any]:
        return [cmd for cmd in self.commands if isinstance(cmd, kind)]

    def __getattr__(self, name: str) -> Any:
        return getattr(self.engine, name)


def write_params(folder: Path, params: Parameters) -> Path:
    """A params/ folder whose default.par holds `params`."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "default.par").write_text(format_par(params, EPOCH), encoding="ascii")
    return folder


def make_app(engine: Any) -> QuadTankApp:
    """The app as the CLI builds it, with a fixed wall clock (the status line's
    "last sample ... ago" must not depend on when the test runs)."""
    return build_app(engine, refresh_interval=0.05, wall_clock=lambda: 0.0)


def manual_engine() -> Engine:
    """An engine in the start-up state on ./params and ./logs."""
    return build_engine(clock="manual", params_dir="params", logs_dir="logs", epoch=EPOCH)


async def open_setup(pilot: Any) -> None:
    """From Main to Setup by its key, as a user does."""
    await pilot.pause()
    await pilot.press("S")
    await pilot.pause()


async def workers_done(app: Any) -> None:
    """Until every worker is done; an exclusive worker (the Design screen's plots)
    that a newer one cancelled while we waited is not a failure."""
    while True:
        try:
            await app.workers.wait_for_complete()
            return
        except WorkerCancelled:
            continue


async def presses_shown(pilot: Any, timeout: float = 2.0) -> None:
    """Until no button shows its last press (Textual's `-active` look, 0.2 s after a
    click or an Enter): a snapshot taken right after a click had the pressed look
    or not depending on the machine's speed (the calibration window's fit failed
    in CI that way, same text, other colours)."""
    deadline = time.monotonic() + timeout
    while pilot.app.screen.query(".-active") and time.monotonic() < deadline:
        await pilot.pause(0.05)


def plot_text(widget: Widget) -> str:
    """What a widget draws, as plain text (a trend renders rich Text)."""
    rendered = widget.render()
    assert isinstance(rendered, Text), type(rendered)
    return rendered.plain


class Wire:
    """Counts the bytes the app's display updates would put on the terminal."""

    def __init__(self, app: QuadTankApp) -> None:
        self.bytes = 0
        self.updates: list[str] = []
        display = app._display

        def counting(screen: Any, renderable: Any) -> None:
            if isinstance(renderable, CompositorUpdate):
                data = renderable.render_segments(app.console)
                self.bytes += len(data.encode())
                self.updates.append(data)
            display(screen, renderable)

        app._display = counting  # type: ignore[method-assign]
