"""The half of an EngineHandle a client answers from what it holds itself.

The loop process's parent (engine/process.py) and a session's client
(session/client.py) both keep a copy of the ring buffers, the defaults, the `.par`
folder and the logs folder; only the snapshot and the commands cross to the loop.
These answers are the same for both, so they are written once here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from quadtank_tui.core.parameters import Parameters
from quadtank_tui.engine.history import History
from quadtank_tui.files.log_writer import log_path
from quadtank_tui.files.par import ParStore


class HeldLocally:
    """history, defaults, par_names, log_exists and logs_dir from the client's own copies."""

    _history: History
    _defaults: Parameters
    _store: ParStore
    _logs_dir: Path

    def history(self, seconds: float | None = None) -> Mapping[str, np.ndarray]:
        return self._history.last(seconds)

    def defaults(self) -> Parameters:
        return self._defaults

    def par_names(self) -> list[str]:
        return self._store.names()

    def log_exists(self, name: str) -> bool:
        return log_path(self._logs_dir, name).exists()

    @property
    def logs_dir(self) -> Path:
        """The folder logs are saved in (the ghost run's window lists it)."""
        return Path(self._logs_dir)
