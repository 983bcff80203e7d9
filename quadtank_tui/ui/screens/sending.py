"""Sending commands to the engine from a screen, and showing what became of them.

Main and Setup are the only parts of the UI that talk to the engine; both send a
window's commands the same way: submit, and when the result comes back (at once
with a manual clock, after the next sample from the loop's thread) notify a
refusal, the warnings and a success message, then redraw from the engine.
"""

from __future__ import annotations

import threading
from concurrent.futures import Future
from typing import Callable

from textual.geometry import Size
from textual.message import Message

from quadtank_tui.engine.commands import Command, CommandResult
from quadtank_tui.engine.handle import EngineHandle
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.labels import command_title
from quadtank_tui.ui.messages import ActionRequested
from quadtank_tui.ui.screens.behind import QuietBehind
from quadtank_tui.ui.widgets.sized import PacksForSize
from quadtank_tui.ui.windows.base import Commands

#: Below this width or height a screen packs tighter (80x24 terminals).
COMPACT_WIDTH, COMPACT_HEIGHT = 110, 34

#: Called with the engine's message instead of the error notification.
OnRefused = Callable[[str], None]
#: Called when the engine applied the command (Exit after a successful Save).
OnDone = Callable[[], None]


class CommandAnswered(Message, bubble=False):
    """The engine's answer to a command, from the engine's thread.  A message rather
    than `call_from_thread`: that waits for the app, and an answer that a slow
    engine (a hung DAQ) gives after Exit would hold the engine's thread (and the
    Exit) or reach a screen already taken down (NoMatches)."""

    def __init__(self, command: Command, future: Future[CommandResult], on_refused: OnRefused | None,
                 on_done: OnDone | None = None) -> None:
        super().__init__()
        self.command, self.future, self.on_refused, self.on_done = command, future, on_refused, on_done


class CommandSender(PacksForSize, QuietBehind):
    """A screen that sends commands; it has `engine`, `snap` (the snapshot it
    shows) and `refresh_view()`, runs its widgets' ActionRequested and packs
    tighter (`-compact`) on a small terminal."""

    engine: EngineHandle
    snap: Snapshot

    def pack(self, size: Size) -> None:
        self.set_class(size.width < COMPACT_WIDTH or size.height < COMPACT_HEIGHT, "-compact")

    async def on_action_requested(self, message: ActionRequested) -> None:
        """A widget's intent runs the action its key runs (see ActionRequested)."""
        message.stop()
        await self.run_action(message.action)

    def refresh_view(self) -> None:
        """Redraw from the engine (each screen says what that means)."""

    def current(self) -> Snapshot:
        """Bring the view up to date and return the snapshot a window opens on, so a
        window never shows values older than the screen behind it."""
        self.refresh_view()
        return self.snap

    def send(self, command: Command, on_refused: OnRefused | None = None,
             on_done: OnDone | None = None) -> None:
        """Submit a command; a refusal goes to `on_refused` or is notified;
        `on_done` runs once it was applied."""
        future = self.engine.submit(command)
        ui_thread = threading.get_ident()

        def deliver(f: Future[CommandResult]) -> None:
            if threading.get_ident() == ui_thread:  # completed on the UI thread itself
                self._result(command, f, on_refused, on_done)
            else:  # thread-safe, never waits on the app, dropped once the screen has closed
                self.post_message(CommandAnswered(command, f, on_refused, on_done))

        if future.done():
            self._result(command, future, on_refused, on_done)
        else:
            future.add_done_callback(deliver)

    def on_command_answered(self, message: CommandAnswered) -> None:
        if self.is_attached:  # not while the app takes the screen down (Exit)
            self._result(message.command, message.future, message.on_refused, message.on_done)

    def _result(self, command: Command, future: Future[CommandResult], on_refused: OnRefused | None,
                on_done: OnDone | None = None) -> None:
        try:
            result = future.result()
        except Exception as exc:  # the engine failed to apply it: say so, go on
            result = CommandResult.refused(f"{type(exc).__name__}: {exc}")
        if not result.ok:
            if on_refused is not None:
                on_refused(result.message)
            else:
                self.notify(result.message, title=command_title(command), severity="error", timeout=6,
                            markup=False)
        for warning in result.warnings:
            self.notify(warning, severity="warning", markup=False)
        if result.ok and result.message:
            self.notify(result.message, timeout=3, markup=False)
        self.refresh_view()
        if result.ok and on_done is not None:
            on_done()

    def send_all(self, commands: Commands | None) -> None:
        """A window's result: send its commands in order (none if cancelled)."""
        for command in commands or ():
            self.send(command)
