"""The Textual application: a thin shell around the Main screen.

`build_app` is the one factory the CLI and the tests use.  The app does not own
the engine: whoever built the engine starts it before and stops it after the app
runs (the CLI does; tests drive a manual-clock engine themselves).
"""

from __future__ import annotations

import asyncio
import gc
import os
import threading
import time
from functools import partial
from typing import Any, Callable, Iterable

from textual.app import SystemCommand
from textual.binding import Binding
from textual.screen import ModalScreen, Screen

from quadtank_tui.engine.handle import EngineHandle
from quadtank_tui.ui import escape_keys
from quadtank_tui.ui.keyorder import OrderedKeys
from quadtank_tui.ui.screens.main import MainScreen
from quadtank_tui.ui.screens.too_small import TooSmallScreen, too_small


class QuadTankApp(OrderedKeys):
    """quadtank: the Lund quadruple-tank lab interface in a terminal."""

    TITLE = "quadtank"
    # Every screen's stylesheet is read here, once, at start: a screen's own
    # CSS_PATH would make Textual reparse the whole stylesheet (every widget's CSS)
    # and restyle the app on the screen's first visit (0.15 s of CPU at the first S,
    # I, D or F1). Their rules start with the screen's or window's type, so they
    # touch nothing else.
    CSS_PATH = ["styles/app.tcss", "styles/main.tcss", "styles/windows.tcss",
                "styles/setup.tcss", "styles/design.tcss", "styles/identify.tcss", "styles/help.tcss"]
    # Exit goes through the Main screen's confirmation (unsaved log, pumps to 0).
    # F1 opens the help from anywhere, a window included (`?` there is text).
    BINDINGS = [Binding("ctrl+q", "request_exit", "Exit", show=False, priority=True),
                Binding("f1", "help", "Help", show=False, priority=True)]

    def __init__(self, engine: EngineHandle, *, refresh_interval: float = 0.05,
                 wall_clock: Callable[[], float] = time.monotonic, resume_gc: bool = False,
                 read_on: Callable[[asyncio.AbstractEventLoop], None] | None = None) -> None:
        # NO_COLOR (no-color.org): Textual then strips every colour (its NoColor
        # filter) only with native ANSI colours; otherwise it paints in greys.
        super().__init__(ansi_color=True if "NO_COLOR" in os.environ else None)
        escape_keys.install()  # Esc then a key, sent together, is not Alt+key
        self.engine = engine
        self.main = MainScreen(engine, refresh_interval=refresh_interval, wall_clock=wall_clock)
        self._aloop: asyncio.AbstractEventLoop | None = None
        # An exit asked for before the app's loop runs (the terminal hung up while
        # the TUI was starting) waits here for on_mount instead of being dropped.
        self._exit_lock = threading.Lock()
        self._early_exit: int | None = None
        self._resume_gc = resume_gc
        self._read_on = read_on
        #: the exercise the TUI follows (app/exercise.py's LiveExercise), None without one
        self.exercise: Any = None
        #: shown first when `quadtank --daq/--par` attached to a running session (ui/windows/attached.py)
        self.attached: Any = None
        #: the user chose, in that window, to stop the session and start a new one
        self.new_session_asked = False

    def on_mount(self) -> None:
        with self._exit_lock:
            self._aloop = asyncio.get_running_loop()
            early = self._early_exit
        if early is not None:
            self.exit(None, early)
            return
        if self._read_on is not None:  # the session's client reads on this loop from now on
            self._read_on(self._aloop)
        self.push_screen(self.main)
        if self.exercise is not None:  # quadtank exercise FILE: its window first
            self.call_after_refresh(self.main.action_exercise)
        if self.attached is not None:  # --daq / --par not applied: said at once
            self.call_after_refresh(self._show_attached)
        self._check_size()
        if self._resume_gc:
            self.call_after_refresh(resume_gc)

    def _show_attached(self) -> None:
        from quadtank_tui.ui.windows.attached import AttachedWindow

        def chosen(new: bool | None) -> None:
            if new:
                self.new_session_asked = True
                self.exit(None, 0)

        self.push_screen(AttachedWindow(self.attached), chosen)

    def on_resize(self) -> None:
        self.call_later(self._check_size)

    def _check_size(self) -> None:
        """Below MIN_SIZE a sentence says so instead of a clipped screen."""
        if self.main not in self.screen_stack:
            return  # not started yet: on_mount checks
        small = too_small(*self.size)
        # Once: one may be under a window opened over it (it goes when back in front).
        if small and not any(isinstance(s, TooSmallScreen) for s in self.screen_stack):
            self.push_screen(TooSmallScreen())
        elif not small and isinstance(self.screen, TooSmallScreen):
            self.pop_screen()

    def exit_soon(self, return_code: int) -> None:
        """Exit with `return_code`, from any thread (the terminal went away: see
        ui/terminal_watch.py): the orderly exit, without the Exit window's questions;
        an unsaved log stays on disk as the partial file."""
        with self._exit_lock:
            aloop = self._aloop
            if aloop is None:
                self._early_exit = return_code
                return
        if not aloop.is_closed():
            aloop.call_soon_threadsafe(self.exit, None, return_code)

    def action_request_exit(self) -> None:
        # From Main or Setup (the original had Exit on both), not over a window,
        # also when a terminal too small to show them hides them (too_small.py).
        front = next(s for s in reversed(self.screen_stack) if not isinstance(s, TooSmallScreen))
        if not isinstance(front, ModalScreen):
            self.main.action_exit()

    def action_help(self) -> None:
        """Every key of every screen and window (`?`, F1); F1 again closes it."""
        from quadtank_tui.ui.screens.help import HelpScreen

        if isinstance(self.screen, HelpScreen):
            self.screen.dismiss(None)
        else:
            self.push_screen(HelpScreen())

    def action_command_palette(self) -> None:
        """Textual's palette, once: with one open under Help (ctrl+p, F1, ctrl+p)
        Textual pushed a second and the app died on the duplicate id (found by
        benchmarks/hardening.py's random keys)."""
        from textual.command import CommandPalette

        from quadtank_tui.ui.palette import Palette

        if self.use_command_palette and not any(isinstance(s, CommandPalette) for s in self.screen_stack):
            self.push_screen(Palette(id="--command-palette"))

    async def action_quit(self) -> None:
        """Textual's own quit (the palette's "Quit"): the same questions as Exit, so
        an unsaved log is never lost by the back door."""
        self.call_later(self.action_request_exit)

    def get_system_commands(self, screen: Screen) -> Iterable[SystemCommand]:
        """The command palette lists every action the screen's keys offer now, each
        once, with its key and what it does.  Textual's "Keys" panel (it squeezed
        the process image, Esc did not close it) is replaced by Help; its "Quit"
        (no question, a log lost) by the screen's Exit."""
        for command in super().get_system_commands(screen):
            if command.title not in ("Keys", "Quit"):
                yield command
        yield SystemCommand("Help", "? or F1 · every key of Main, Setup and each window", self.action_help)
        if isinstance(screen, ModalScreen):
            return
        seen = {"app.help"}
        for active in screen.active_bindings.values():
            b = active.binding
            if active.node is screen and active.enabled and b.description and b.action not in seen:
                seen.add(b.action)
                yield SystemCommand(b.description, f"{self.get_key_display(b)} · {b.tooltip or b.description}",
                                    partial(self.call_later, screen.run_action, b.action))


def resume_gc() -> None:
    """After the first frame (the CLI paused the collector for the start-up,
    commands.pause_gc): what exists now stays, so it is frozen out of every later
    collection (shorter pauses for the life of the TUI), then collection resumes."""
    gc.freeze()
    gc.enable()


def build_app(engine: EngineHandle, *, refresh_interval: float = 0.05,
              wall_clock: Callable[[], float] = time.monotonic, resume_gc: bool = False,
              read_on: Callable[[asyncio.AbstractEventLoop], None] | None = None,
              exercise: Any = None, attached: Any = None) -> QuadTankApp:
    """The app on `engine`; `refresh_interval` is the UI timer in seconds (raise it
    on a slow link); `wall_clock` is injected so tests are deterministic;
    `resume_gc`: the caller paused the garbage collector for the start
    (commands.pause_gc); `read_on`: given the app's event loop once it runs (a
    session client then reads its socket there: session/client.py read_on);
    `attached`: the AttachedNotice of options a running session did not take."""
    app = QuadTankApp(engine, refresh_interval=refresh_interval, wall_clock=wall_clock, resume_gc=resume_gc,
                      read_on=read_on)
    app.exercise = exercise  # an app/exercise.LiveExercise: `x` on Main opens its window
    app.attached = attached  # a ui.windows.attached.AttachedNotice: opened first
    return app
