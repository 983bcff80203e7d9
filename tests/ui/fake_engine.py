"""A test double of the engine (EngineHandle) until the real one is merged.

Honest where the UI depends on it: parameters are validated by the Parameters
model (a refusal carries ParameterError's message), modes follow M1-M3 (Active
needs a DAQ; Reset returns to the operating point and pauses; Manual<->Automatic
adjusts the means), the plant is the real nonlinear model stepped by
core.plant.advance.  What it does not have: controllers (in Automatic the inputs
are held), wave shapes (the generators give their means) and files (a log only
counts rows).  Commands apply at once and return completed futures; time moves
only in `run_for`, so screens are deterministic.
"""

from __future__ import annotations

import dataclasses
from concurrent.futures import Future
from typing import Callable, Mapping

import numpy as np

from quadtank_tui.core.parameters import PRESET, REFERENCE_SECTIONS, Parameters
from quadtank_tui.core.plant import advance
from quadtank_tui.core.validation import ParameterError
from quadtank_tui.engine import commands as c
from quadtank_tui.engine.handle import SIGNALS
from quadtank_tui.engine.snapshot import LogStatus, LoopStats, Snapshot


class FakeEngine:
    def __init__(self, params: Parameters = PRESET, *, active_available: bool = False,
                 wall: Callable[[], float] = lambda: 0.0) -> None:
        self.params = params
        self.wall = wall
        self.last_wall = wall()
        self._defaults = params
        self.active_available = active_available
        self.operation, self.state, self.control = "Simul", "Pause", params.control.mode.value
        self.t, self.k = 0.0, 0
        self.y = tuple(params.simulation.op_points)
        self.u = (params.references[0].mean, params.references[1].mean)
        self.log = LogStatus(points=params.logging.points, file=params.logging.log_file)
        self.saved: set[str] = set()
        self.rows: dict[str, list[float]] = {s: [] for s in SIGNALS}
        self.commands: list[c.Command] = []
        self._record()

    # --- EngineHandle -------------------------------------------------------------

    def snapshot(self) -> Snapshot:
        w = (self.params.references[0].mean, self.params.references[1].mean)
        r = w if self.control == "Automatic" else (self.y[0], self.y[1])
        return Snapshot(
            t=self.t, k=self.k, y=self.y, u=self.u, w=w, r=r,  # type: ignore[arg-type]
            operation=self.operation, state=self.state, control=self.control,
            params=self.params, speed=1.0, realtime=False,
            active_available=self.active_available, backend="simulator (fake)",
            log=self.log, stats=LoopStats(samples=self.k, last_sample_wall=self.last_wall),
        )

    def history(self, seconds: float | None = None) -> Mapping[str, np.ndarray]:
        t = np.asarray(self.rows["t"])
        keep = slice(None) if seconds is None else t >= self.t - seconds
        return {s: np.asarray(self.rows[s])[keep] for s in SIGNALS}

    def submit(self, command: c.Command) -> Future[c.CommandResult]:
        self.commands.append(command)
        future: Future[c.CommandResult] = Future()
        try:
            future.set_result(self._apply(command) or c.CommandResult(True))
        except ParameterError as exc:
            future.set_result(c.CommandResult.refused(str(exc)))
        return future

    def defaults(self) -> Parameters:
        return self._defaults

    def par_names(self) -> list[str]:
        return ["default", "minphase", "nonminphase"]

    def log_exists(self, name: str) -> bool:
        return name in self.saved

    # --- commands -------------------------------------------------------------------

    def _apply(self, cmd: c.Command) -> c.CommandResult | None:
        if isinstance(cmd, c.SetParams):
            self.params = self.params.with_values(cmd.values)
        elif isinstance(cmd, c.SetDefaults):
            self.params = self.params.with_defaults(cmd.keys, self._defaults)
        elif isinstance(cmd, c.SetOperation):
            if cmd.operation == "Active" and not self.active_available:
                return c.CommandResult.refused("Active needs a DAQ backend")
            self.operation = cmd.operation
        elif isinstance(cmd, c.SetState):
            if cmd.state == "Reset":
                self.y = tuple(self.params.simulation.op_points)
                self.state = "Pause"
            else:
                self.state = cmd.state
        elif isinstance(cmd, c.SetControlMode):
            if cmd.mode != self.control:
                source = (self.y[0], self.y[1]) if cmd.mode == "Automatic" else self.u
                self.params = self.params.with_values(
                    {f"{s}.Mean": round(v, 6) for s, v in zip(REFERENCE_SECTIONS, source)})
                self.control = cmd.mode
        elif isinstance(cmd, c.NudgeMean):
            key = f"{REFERENCE_SECTIONS[cmd.channel - 1]}.Mean"
            self.params = self.params.with_value(key, round(self.params.get(key) + cmd.delta, 6))
        elif isinstance(cmd, c.AddWater):
            if self.operation != "Simul":
                return c.CommandResult.refused("water can be added in Simul only")
            y = list(self.y)
            y[cmd.tank - 1] = min(1.0, max(0.0, y[cmd.tank - 1] + cmd.amount))
            self.y = tuple(y)
            self._record()
        elif isinstance(cmd, c.LogOn):
            lg = self.params.logging
            self.log = LogStatus(active=True, points=lg.points, file=lg.log_file)
        elif isinstance(cmd, c.LogOff):
            self.log = dataclasses.replace(self.log, active=False)
        elif isinstance(cmd, c.LogSave):
            name = cmd.name or self.log.file
            if name in self.saved and not cmd.overwrite:
                return c.CommandResult.refused(f"logs/{name}.log exists")
            self.saved.add(name)
            self.log = dataclasses.replace(self.log, active=False, unsaved=False, saved_path=f"logs/{name}.log")
        elif isinstance(cmd, c.LogDiscard):
            self.log = dataclasses.replace(self.log, active=False, unsaved=False, rows=0)
        elif isinstance(cmd, (c.ResetControllers, c.SetSpeed)):
            pass
        else:
            return c.CommandResult.refused(f"{type(cmd).__name__} is not in the fake engine")
        return None

    # --- time -----------------------------------------------------------------------

    def run_for(self, seconds: float) -> None:
        """Advance `seconds` of process time (only in Run)."""
        if self.state != "Run":
            return
        plant = self.params.plant()
        ts = self.params.tsamp
        for _ in range(round(seconds / ts)):
            if self.control == "Manual":
                self.u = tuple(min(1.0, max(0.0, r.mean)) for r in self.params.references)
            h = [v * plant.hmax for v in self.y]
            h = advance(h, [10 * v for v in self.u], ts, plant)
            self.y = tuple(x / plant.hmax for x in h)
            self.t = round(self.t + ts, 9)
            self.k += 1
            self.last_wall = self.wall()
            if self.log.active:
                rows = self.log.rows + 1
                self.log = dataclasses.replace(self.log, rows=rows, unsaved=True,
                                               active=rows < self.log.points)
            self._record()

    def _record(self) -> None:
        w = (self.params.references[0].mean, self.params.references[1].mean)
        values = dict(t=self.t, y1=self.y[0], y2=self.y[1], y3=self.y[2], y4=self.y[3],
                      u1=self.u[0], u2=self.u[1], ref1=w[0], ref2=w[1])
        for s in SIGNALS:
            self.rows[s].append(values[s])
