"""`quadtank run ... --detach`: a scripted experiment driven by a session process.

The session samples as it always does; before each sample the script's due events
are applied (engine.experiment.apply_due, as `quadtank run` does), and once the
run's duration has passed the log is saved and the summary written, as `quadtank
run` prints them, to the session's output file; then the session ends.  Clients
attach to watch it (read-only: the script is the operator).
"""

from __future__ import annotations

import collections

from quadtank_tui.engine.experiment import apply_due
from quadtank_tui.engine.headless import HeadlessRun, finish_headless
from quadtank_tui.engine.runner import LoopTime


class ScriptedRun:
    def __init__(self, run: HeadlessRun) -> None:
        self.run = run
        script = run.script
        self._events = collections.deque(script.events if script else ())
        self._name = script.file if script else ""
        self._elapsed = LoopTime(run.engine.loop.h)

    def step(self) -> bool:
        """The script's due events, then one sample; True once the run is over."""
        engine = self.run.engine
        apply_due(engine, self._events, self._elapsed, self._name)
        h = engine.loop.h
        engine.step()
        real = engine.loop.backend is not engine.loop.sim
        self._elapsed.add(h, 1 + engine.missed if real else 1)
        return self._elapsed.reached(self.run.duration)

    def finish(self) -> str:
        """Save the log and print the summary (to the session's output); the
        session's reason to stop."""
        result = finish_headless(self.run)
        for warning in result.warnings:
            print(f"quadtank: warning: {warning}")
        print(result.text, flush=True)
        acted = "; the interlock held pumps at 0 (see its output)" if self.run.engine.loop.interlock.acted else ""
        if result.log is None:
            return f"the run is over; no log was written (see its output){acted}"
        return f"the run is over; its log is {result.log}{acted}"
