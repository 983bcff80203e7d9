"""A test double of the engine (EngineHandle) for the Setup screen, until the real
engine is merged.

Honest where the Setup screen depends on it: SetParams and SetDefaults go through
the Parameters model (a refusal carries ParameterError's message, nothing half
applied); LoadPar and SavePar go through the real ParStore in a folder the test
gives (reserved names, file/line/key errors, refusing to overwrite without
`overwrite`).  It has no loop: time stands still, commands apply at once and
return completed futures.
"""

from __future__ import annotations

from concurrent.futures import Future
from pathlib import Path
from typing import Mapping

import numpy as np

from quadtank_tui.core.parameters import Parameters
from quadtank_tui.core.validation import ParameterError
from quadtank_tui.engine import commands as c
from quadtank_tui.engine.handle import SIGNALS
from quadtank_tui.engine.snapshot import LogStatus, LoopStats, Snapshot
from quadtank_tui.files.par import ParFileError, ParStore
from quadtank_tui.files.shipped import write_shipped


class SetupFakeEngine:
    def __init__(self, params_dir: Path) -> None:
        write_shipped(params_dir)
        self.store = ParStore(params_dir)
        self._defaults = self.store.defaults().params
        self.params = self._defaults
        self.state = "Pause"
        self.commands: list[c.Command] = []

    def snapshot(self) -> Snapshot:
        p = self.params
        y = tuple(p.simulation.op_points)
        w = (p.references[0].mean, p.references[1].mean)
        return Snapshot(
            t=0.0, k=0, y=y, u=w, w=w, r=(y[0], y[1]),  # type: ignore[arg-type]
            operation="Simul", state=self.state, control=p.control.mode.value, params=p, speed=1.0,
            realtime=False, active_available=False, backend="simulator (fake)", log=LogStatus(),
            stats=LoopStats(),
        )

    def history(self, seconds: float | None = None) -> Mapping[str, np.ndarray]:
        return {s: np.zeros(0) for s in SIGNALS}

    def defaults(self) -> Parameters:
        return self._defaults

    def par_names(self) -> list[str]:
        return self.store.names()

    def log_exists(self, name: str) -> bool:
        return False

    def submit(self, command: c.Command) -> Future[c.CommandResult]:
        self.commands.append(command)
        future: Future[c.CommandResult] = Future()
        try:
            future.set_result(self._apply(command))
        except (ParameterError, ParFileError) as exc:
            future.set_result(c.CommandResult.refused(str(exc)))
        return future

    def _apply(self, cmd: c.Command) -> c.CommandResult:
        if isinstance(cmd, c.SetParams):
            self.params = self.params.with_values(cmd.values)
        elif isinstance(cmd, c.SetDefaults):
            self.params = self.params.with_defaults(cmd.keys, self._defaults)
        elif isinstance(cmd, c.LoadPar):
            read = self.store.load(cmd.name)
            self.params = read.params
            return c.CommandResult(True, f"loaded {cmd.name}", warnings=read.warnings)
        elif isinstance(cmd, c.SavePar):
            if self.store.exists(cmd.name) and not cmd.overwrite and cmd.name.lower() not in ("default", "preset"):
                return c.CommandResult.refused(f"{self.store.path_of(cmd.name)} exists")
            return c.CommandResult(True, f"saved {self.store.save(cmd.name, self.params)}")
        elif isinstance(cmd, c.SetState):
            self.state = "Pause" if cmd.state == "Reset" else cmd.state
        else:
            return c.CommandResult.refused(f"{type(cmd).__name__} is not in the Setup fake engine")
        return c.CommandResult(True)
