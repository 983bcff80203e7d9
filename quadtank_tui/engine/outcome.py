"""What a command comes to: the refusal its exception stands for, and the
CommandResult of work it handed to a thread (a log's file, a `.par` written)."""

from __future__ import annotations

from concurrent.futures import Future
from typing import Callable, TypeVar

from quadtank_tui.core.plants.common import PlantError
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.engine.commands import CommandResult
from quadtank_tui.engine.logsession import LogRefused
from quadtank_tui.files.log_writer import LogFileError
from quadtank_tui.files.par import ParFileError

T = TypeVar("T")


def refusal(exc: Exception) -> CommandResult | None:
    """The refusal an exception of a command stands for (None: a bug, not a refusal)."""
    if isinstance(exc, (ParameterError, KeyError, PlantError, ParFileError, LogFileError, LogRefused, ValueError)):
        message = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        return CommandResult.refused(str(message))
    if isinstance(exc, OSError):
        return CommandResult.refused(f"{getattr(exc, 'filename', '') or ''} {exc.strerror or exc}".strip())
    return None


def resolved(result: CommandResult) -> Future[CommandResult]:
    """A Future that already holds `result` (what begin() hands back for a command done at once)."""
    fut: Future[CommandResult] = Future()
    fut.set_result(result)
    return fut


def then(fut: Future[T], make: Callable[[T], CommandResult]) -> Future[CommandResult]:
    """The CommandResult of a file operation: `make(value)`, or the refusal its
    exception stands for."""
    out: Future[CommandResult] = Future()

    def done(f: Future[T]) -> None:
        try:
            result = make(f.result())
        except Exception as exc:  # noqa: BLE001 - every outcome resolves the command
            result = refusal(exc) or CommandResult.refused(f"{type(exc).__name__}: {exc}")
        out.set_result(result)

    fut.add_done_callback(done)
    return out
