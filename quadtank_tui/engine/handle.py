"""What the UI (and the CLI) may use of the engine: a read side and one write door.

Attributes down, messages up: the UI reads `snapshot()` and `history()` on its own
timer and sends `Command`s through `submit`; it holds no control logic.

A handle on a lab session (one that outlives the screen and others may watch) also
offers a :class:`LabSession`: whose it is, who drives it, detach or stop on Exit.
The screen asks for it (`lab_session_of`) instead of guessing from the handle's type.
"""

from __future__ import annotations

from concurrent.futures import Future
from pathlib import Path
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

    @property
    def logs_dir(self) -> Path:
        """The folder logs are saved in (the loop's, wherever this screen started)."""


class LabSession(Protocol):
    """What a screen attached to a lab session offers beyond the loop."""

    @property
    def session_id(self) -> str:
        """The session's id (`quadtank attach ID` comes back to it)."""

    @property
    def started(self) -> str:
        """When it started (ISO 8601): with the id, a key no later session reuses."""

    @property
    def operating(self) -> bool:
        """This screen drives it (else it observes, read-only)."""

    @property
    def gone(self) -> bool:
        """The connection is closed: the session ended, died, or this screen left."""

    @property
    def ended(self) -> str | None:
        """Why it ended, when it stopped in order."""

    @property
    def dropped(self) -> str | None:
        """Why the session dropped this screen, which it did while running on."""

    @property
    def policy(self) -> str:
        """What it does once no operator is attached (the lab's policy), one sentence."""

    def session_banner(self) -> str:
        """One line for the screen: whose session, who drives it, or why it is gone."""

    def stop_on_exit(self) -> None:
        """Exit chose to stop the session (pumps at 0, log kept) rather than detach."""


def lab_session_of(handle: object) -> LabSession | None:
    """The lab session `handle` offers, if any: a session client's `lab_session()`;
    None from a private session's (it ends with its screen: nothing to detach from)
    and from a handle that names no such offer (the in-process engine of the tests
    and benchmarks)."""
    offer = getattr(handle, "lab_session", None)
    return offer() if callable(offer) else None
