"""The Textual application: a thin shell around the Main screen.

`build_app` is the one factory the CLI and the tests use.  The app does not own
the engine: whoever built the engine starts it before and stops it after the app
runs (the CLI does; tests drive a manual-clock engine themselves).
"""

from __future__ import annotations

import time
from functools import partial
from typing import Callable, Iterable

from textual.app import App, SystemCommand
from textual.binding import Binding
from textual.screen import ModalScreen, Screen

from quadtank_tui.engine.handle import EngineHandle
from quadtank_tui.ui.keyorder import OrderedKeys
from quadtank_tui.ui.screens.main import MainScreen


class QuadTankApp(OrderedKeys):
    """quadtank: the Lund quadruple-tank lab interface in a terminal."""

    TITLE = "quadtank"
    CSS_PATH = ["styles/app.tcss", "styles/main.tcss", "styles/windows.tcss"]
    # Exit goes through the Main screen's confirmation (unsaved log, pumps to 0).
    BINDINGS = [Binding("ctrl+q", "request_exit", "Exit", show=False, priority=True)]

    def __init__(self, engine: EngineHandle, *, refresh_interval: float = 0.05,
                 wall_clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__()
        self.engine = engine
        self.main = MainScreen(engine, refresh_interval=refresh_interval, wall_clock=wall_clock)

    def on_mount(self) -> None:
        self.push_screen(self.main)

    def action_request_exit(self) -> None:
        # From Main or Setup (the original had Exit on both), not over a window.
        if not isinstance(self.screen, ModalScreen):
            self.main.action_exit()

    async def action_quit(self) -> None:
        """Textual's own quit (the palette's "Quit"): the same questions as Exit, so
        an unsaved log is never lost by the back door."""
        self.call_later(self.action_request_exit)

    def get_system_commands(self, screen: Screen) -> Iterable[SystemCommand]:
        """The command palette lists every action the screen's keys offer now."""
        yield from super().get_system_commands(screen)
        if isinstance(screen, ModalScreen):
            return
        for key, active in screen.active_bindings.items():
            b = active.binding
            if active.node is screen and active.enabled and b.description:
                yield SystemCommand(b.description, f"key {key}",
                                    partial(self.call_later, screen.run_action, b.action))


def build_app(engine: EngineHandle, *, refresh_interval: float = 0.05,
              wall_clock: Callable[[], float] = time.monotonic) -> QuadTankApp:
    """The app on `engine`; `refresh_interval` is the UI timer in seconds (raise it
    on a slow link); `wall_clock` is injected so tests are deterministic."""
    return QuadTankApp(engine, refresh_interval=refresh_interval, wall_clock=wall_clock)
