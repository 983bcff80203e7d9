"""The steady-state calibration on the rig (Desautel 2.3) as the loop runs it: one
step per sample instead of the control law, while the loop is paused.

The procedure's logic is core's
(core.calibration.procedure.CalibrationRun: settling, the operator's heights, the
fit); here it meets the rig: the pumps held at the step's voltages every sample
(so the rig's watchdog sees the link alive), the raw sensor volts read, and the
pumps set to 0 whenever the procedure stops holding them.
"""

from __future__ import annotations

import math
from pathlib import Path

from quadtank_tui.core.calibration.fits import CalibrationError
from quadtank_tui.core.calibration.procedure import CalibrationRun, CalibrationStatus, SettleRule
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.plants import Plant
from quadtank_tui.engine.backend import Levels4, Pair, ProcessBackend
from quadtank_tui.engine.commands import CalibrationHeights, CommandResult, StartCalibration


class RigCalibration:
    """The calibration of the rig the loop drives, if one was started: `run` (None:
    none, or forgotten) and the files its result may go to (the DAQ file, the
    parameter folder)."""

    def __init__(self) -> None:
        self.run: CalibrationRun | None = None
        self.files = ("", "")

    @property
    def active(self) -> bool:
        """The procedure holds the pumps: the loop must not sample."""
        return self.run is not None and self.run.active

    def start(self, daq: ProcessBackend, cmd: StartCalibration, plant: Plant, h: float,
              par_dir: Path) -> CommandResult:
        """Start holding the pumps (refused on a backend without raw reads: the
        simulator, whose sensors need no calibration)."""
        if not hasattr(daq, "read_raw_volts"):
            return CommandResult.refused("calibration runs on the rig: switch to Active first "
                                         "(the simulation's sensors are exact)")
        if self.active:
            return CommandResult.refused("a calibration is running: cancel it first")
        try:
            if not (isinstance(cmd.window, (int, float)) and math.isfinite(cmd.window) and cmd.window > 0):
                raise CalibrationError(f"the settling window must be a time > 0 s, got {cmd.window!r}")
            reads = max(2, round(cmd.window / h))
            run = CalibrationRun(tuple(cmd.volts), SettleRule(reads, cmd.tol, cmd.timeout), h,
                                 tanks=len(plant.states), pumps=len(plant.inputs))
        except CalibrationError as exc:
            return CommandResult.refused(str(exc))
        self.run = run
        config = getattr(daq, "config", None)
        source = str(getattr(config, "source", ""))
        self.files = (source if Path(source).is_file() else "", str(par_dir))
        return CommandResult(True)

    def tick(self, daq: ProcessBackend, plant: Plant) -> tuple[Pair, Levels4, bool]:
        """One sample: the pumps held (normalized u written), the raw sensors read
        while settling; (u, levels, whether the pumps are still held: False when the
        procedure timed out, and the caller sets them to 0)."""
        run = self.run
        assert run is not None
        v = run.pumps()
        scales = [s.full_scale for s in plant.inputs] + [FULL_SCALE_V, FULL_SCALE_V]
        u = [v[i] / scales[i] if i < run.pumps_used else 0.0 for i in range(2)]
        written = (u[0], u[1])
        daq.write_pumps(written)
        volts = daq.read_raw_volts()  # type: ignore[attr-defined]  # checked at start
        levels: Levels4 = daq.levels_from_volts(volts)  # type: ignore[attr-defined]
        return written, levels, run.feed(volts) in ("settling", "heights")

    def heights(self, cmd: CalibrationHeights) -> CommandResult:
        """The operator's scale readings for the step that settled."""
        if self.run is None:
            return CommandResult.refused("no calibration is running")
        try:
            self.run.heights(tuple(cmd.levels))
        except (CalibrationError, TypeError, ValueError) as exc:
            return CommandResult.refused(str(exc))
        return CommandResult(True)

    def cancel(self) -> bool:
        """Stop it while it runs (True: the caller sets the pumps to 0); afterwards,
        forget it (the window closed)."""
        if self.run is None:
            return False
        if self.run.active:
            self.run.cancel()
            return True
        self.run = None
        return False

    def fail(self, why: str) -> None:
        """The loop faulted while the procedure held the pumps."""
        if self.run is not None and self.run.active:
            self.run.fail(why)

    def forget(self) -> None:
        """A calibration belongs to the rig it ran on: another backend, none."""
        self.run = None

    def status(self) -> CalibrationStatus | None:
        if self.run is None:
            return None
        return CalibrationStatus.of(self.run, daq_file=self.files[0], par_dir=self.files[1])
