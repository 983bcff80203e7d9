"""What the UI (and the CLI) may use of the engine: a read side and one write door.

Attributes down, messages up: the UI reads `snapshot()` and `history()` on its own
timer and sends `Command`s through `submit`; it holds no control logic.
"""

from __future__ import annotations

from concurrent.futures import Future
from typing import Mapping, Protocol

import numpy as np

from quadtank_tui.core.parameters import Parameters
from quadtank_tui.engine.commands import Command, CommandResult
from quadtank_tui.engine.snapshot import Snapshot

#: Signals kept in the ring buffers, by the names the plot types use.
SIGNALS = ("t", "y1", "y2", "y3", "y4", "u1", "u2", "ref1", "ref2")


class EngineHandle(Protocol):
    def snapshot(self) -> Snapshot:
        """The latest published snapshot (cheap; call it as often as you like)."""

    def history(self, seconds: float | None = None) -> Mapping[str, np.ndarray]:
        """The last `seconds` of process time (all kept if None) of every signal in
        SIGNALS, as read-only copies of equal length, oldest first."""

    def submit(self, command: Command) -> Future[CommandResult]:
        """Queue a command; it is applied between samples.  Thread-safe."""

    def defaults(self) -> Parameters:
        """The values that count as "default" for the modified marking (S6)."""

    def par_names(self) -> list[str]:
        """Names of the parameter files in the parameter folder, without `.par`."""

    def log_exists(self, name: str) -> bool:
        """Whether `logs/<name>.log` exists (the UI asks before overwriting)."""
