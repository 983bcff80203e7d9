"""The messages between a loop's driver and the process that hosts it, as values.

The loop process (:mod:`engine.process`) and its parent talk over a pipe: commands
go down, results and the child's life events come up.  Each message is a frozen
dataclass, so a reader matches on its type and its fields have names (no ``msg[1]``
that means an id here and a reason there), and mypy checks both ends.  They hold
only values that pickle (commands, results, parameters, strings); the snapshots and
trends travel through shared memory (:mod:`engine.shared`), not here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Union

from quadtank_tui.core.parameters import Parameters
from quadtank_tui.engine.commands import Command, CommandResult

# --- down: parent -> loop -------------------------------------------------------------------


@dataclass(frozen=True)
class Start:
    """Start sampling (the engine was built paused, ready to read)."""


@dataclass(frozen=True)
class Submit:
    """Apply `command` between samples and answer with a :class:`Result` of the same id
    (also a session client's message: session.protocol)."""

    id: int
    command: Command


@dataclass(frozen=True)
class Stop:
    """Stop the loop: pumps to 0, logging stopped (rows kept), then :class:`Stopped`."""


ToLoop = Union[Start, Submit, Stop]

# --- up: loop -> parent ---------------------------------------------------------------------


@dataclass(frozen=True)
class Ready:
    """The engine is built and its first snapshot published; `defaults` are what
    counts as default (S6)."""

    defaults: Parameters


@dataclass(frozen=True)
class Failed:
    """The engine could not be built; `reason` says why (the parent raises it)."""

    reason: str


@dataclass(frozen=True)
class Result:
    """What became of the :class:`Submit` with this `id`."""

    id: int
    result: CommandResult


@dataclass(frozen=True)
class Stopped:
    """The loop stopped, pumps at 0; `crash` is why, if it was not asked to."""

    crash: str | None = None


FromLoop = Union[Ready, Failed, Result, Stopped]

_DOWN = (Start, Submit, Stop)
_UP = (Ready, Failed, Result, Stopped)


class MessageError(ValueError):
    """Something on the pipe that is not one of these messages."""


def to_loop(message: object) -> ToLoop:
    """`message` if it is a parent -> loop message, else MessageError."""
    if isinstance(message, _DOWN):
        return message
    raise MessageError(f"not a message for the loop: {type(message).__name__}")


def from_loop(message: object) -> FromLoop:
    """`message` if it is a loop -> parent message, else MessageError."""
    if isinstance(message, _UP):
        return message
    raise MessageError(f"not a message from the loop: {type(message).__name__}")
