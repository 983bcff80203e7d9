"""`quadtank run ... --detach`: a scripted experiment driven by a session process.

The session samples as it always does; before each sample the script's due events
are applied (engine.experiment.apply_due, as `quadtank run` does), and once the
run's duration has passed the log is saved and the summary written, as `quadtank
run` prints them, to the session's output file; then the session ends.  Clients
attach to watch it (read-only: the script is the operator).

Before the session is started the launcher rehearses the run (`rehearse`): the same
script on a manual clock, up to its last event, so a refusal that would end the
detached run (a script that changes the sampling time while logging) is said in
the terminal with exit 2, as `quadtank run` without --detach says it, instead of
in an output file nobody reads.
"""

from __future__ import annotations

import collections
import tempfile
import time
from pathlib import Path

from quadtank_tui.core.disturbance import updated
from quadtank_tui.engine.backend import Levels4, Pair, ProcessBackend
from quadtank_tui.engine.experiment import apply_due
from quadtank_tui.engine.headless import HeadlessRun, finish_headless, prepare_headless
from quadtank_tui.engine.driver import Driver, LoopTime
from quadtank_tui.files.script import Script

#: Wall seconds the launcher spends rehearsing a detached run's script at most.
REHEARSAL_BUDGET = 3.0


class ScriptedRun:
    """The script of a detached run: its due events ahead of each sample of the
    driver, which ends the drive once the run's duration has passed."""

    def __init__(self, run: HeadlessRun) -> None:
        self.run = run
        script = run.script
        self._events = collections.deque(script.events if script else ())
        self._name = script.file if script else ""
        self._told = False  # the log's fault said in the output

    @property
    def pending(self) -> bool:
        """Events of the script not applied yet."""
        return bool(self._events)

    @property
    def duration(self) -> float:
        return self.run.duration

    def before(self, elapsed: LoopTime) -> None:
        """The script's events due at `elapsed` (ValueError: a refused one, the
        script's error naming its file and line)."""
        apply_due(self.run.engine, self._events, elapsed, self._name)
        if not self._told and self.run.engine.log_failed is not None:  # said in the output when it happens
            self._told = True
            print(f"LOG FAULT at t = {elapsed.seconds:g} s: {self.run.engine.log_failed}", flush=True)

    def finish(self) -> str:
        """Save the log and print the summary (to the session's output); the
        session's reason to stop."""
        result = finish_headless(self.run)
        for warning in result.warnings:
            print(f"quadtank: warning: {warning}")
        print(result.text, flush=True)
        acted = "; the interlock held pumps at 0 (see its output)" if self.run.engine.interlock_acted else ""
        if result.log is None:
            return f"the run is over; no log was written (see its output){acted}"
        return f"the run is over; its log is {result.log}{acted}"


class _StandIn(ProcessBackend):
    """The rig in a rehearsal: Active (so the engine refuses what it refuses on a
    rig) and still at mid levels; its pumps go nowhere."""

    kind = "Active"
    description = "rehearsal"

    def read_levels(self) -> Levels4:
        return (0.5, 0.5, 0.5, 0.5)

    def write_pumps(self, u: Pair) -> None:
        pass

    def safe_state(self) -> None:
        pass


def rehearse(*, par: str | None, script: Script | None, duration: float, out: Path, seed: int | None,
             params_dir: Path, active: bool, disturbance_pumps: bool = False,
             budget: float = REHEARSAL_BUDGET) -> str | None:
    """Run the detached run's script on a manual clock, writing only to a temporary
    folder, until its last event has been applied: raises the ValueError (a
    ScriptError naming file, event and line) the session would stop with.  `active`:
    on a stand-in rig (the run drives a DAQ), with disturbance pumps if the rig has
    them (`disturbance_pumps`: an IST rig).  A rehearsal stops after `budget` s of
    wall time (a sample costs about 0.1 ms: 10 min of script at 0.1 s is a
    second): then a warning saying how far the script was checked, else None."""
    with tempfile.TemporaryDirectory(prefix="quadtank-rehearsal-") as folder:
        prepared = prepare_headless(par=par, script=script, duration=duration, out=Path(folder) / out.name,
                                    seed=seed, clock="manual", params_dir=params_dir,
                                    daq=(_PumpedStandIn() if disturbance_pumps else _StandIn()) if active else None)
        run = ScriptedRun(prepared)
        end = time.monotonic() + budget
        checked: list[str] = []
        driver: Driver

        def before(elapsed: LoopTime) -> None:
            run.before(elapsed)
            if not run.pending:
                driver.stop()
            elif time.monotonic() > end:
                last = max(e.at for e in prepared.script.events) if prepared.script else 0.0
                checked.append(f"the script was checked up to {elapsed.seconds:g} s of its last event at "
                               f"{last:g} s (a refusal after that ends the session: quadtank sessions says why)")
                driver.stop()

        driver = Driver(prepared.engine, duration=duration, before=before)
        try:
            if run.pending:
                driver.run()
        finally:
            prepared.engine.stop()
    return checked[0] if checked else None


class _PumpedStandIn(_StandIn):
    """The stand-in of a rig with disturbance pumps (an IST rig): they take what the
    rig takes (0..1 of full PWM)."""

    disturbances = (0.0, 0.0)

    def set_disturbances(self, d1: float | None, d2: float | None) -> None:
        updated(self.disturbances, d1, d2)  # ValueError as the rig's
