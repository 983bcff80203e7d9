"""A designed controller pair tried on the nonlinear simulator, through the real
engine, headless (the last part of the 2x2 check of `quadtank design --par`).

The thesis's experiment (Nunes 1998, appendix A.4): Manual at the operating
point's pump voltages, Run until steady, Automatic (bumpless: the references
start at the measured levels), then a step of 0.1 (1 V) on one reference.  The
figures are those of `quadtank run` (core.metrics): overshoot, settling time
(2 % band), IAE, plus the largest excursion the step causes in the other loop.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from quadtank_tui.core.design.apply import controller_values
from quadtank_tui.core.design.controller import PID
from quadtank_tui.core.metrics import LoopMetrics, loop_metrics
from quadtank_tui.core.plant import FULL_SCALE_V, steady_state_inputs
from quadtank_tui.engine.commands import SetControlMode, SetParams, SetState
from quadtank_tui.engine.headless import must
from quadtank_tui.engine.history import DEFAULT_CAPACITY
from quadtank_tui.engine.runner import Engine, build_engine, load_parameters
from quadtank_tui.files.par import ParStore

STEP = 0.1  # normalized: 1 V, about 2 cm
SETTLE_BEFORE = 200.0  # s in Manual before Automatic
AUTO_BEFORE_STEP = 10.0  # s in Automatic before the step
TSAMP_MS = 1000.0  # the thesis's experiments sample at 1 s

@dataclass(frozen=True)
class StepCheck:
    loop: int
    step: LoopMetrics  # of the stepped loop, from the step on
    other_peak: float  # largest |y_other - y_other(step)|, normalized
    duration: float


def run_step(pair: Sequence[PID], *, par: str | Path | None = None, loop: int = 1,
             duration: float = 600.0, params_dir: Path = Path("params"),
             logs_dir: Path = Path("logs")) -> StepCheck:
    """Step reference `loop` by STEP with the pair running; figures after the step."""
    params, _ = load_parameters(par, ParStore(params_dir))
    p = params.plant()
    h = params.operating_levels()
    v = steady_state_inputs(h[0], h[1], p).v
    engine: Engine = build_engine(par, clock="manual", params_dir=params_dir,
                                  logs_dir=logs_dir, threaded=False,
                                  history_capacity=max(DEFAULT_CAPACITY, int(SETTLE_BEFORE + duration) + 100))
    try:
        setup = {"SAMPLING TIME.TSamp": TSAMP_MS, **controller_values(pair)}
        for i, sec in ((0, "REFERENCE ONE"), (1, "REFERENCE TWO")):
            setup.update({f"{sec}.Mean": v[i] / FULL_SCALE_V, f"{sec}.On": 0})
        for command in (SetControlMode("Manual"), SetParams(setup), SetState("Run")):
            must(engine.submit(command).result())
        engine.run_for(SETTLE_BEFORE)
        must(engine.submit(SetControlMode("Automatic")).result())
        engine.run_for(AUTO_BEFORE_STEP)  # as the sample session: the step 10 s later
        key = f"REFERENCE {'ONE' if loop == 1 else 'TWO'}.Mean"
        mean = engine.snapshot().params.get(key)
        must(engine.submit(SetParams({key: mean + STEP})).result())
        engine.run_for(duration)
        hist = engine.history()
    finally:
        engine.stop()
    t = hist["t"]
    after = t >= SETTLE_BEFORE - 1e-9
    i, o = loop, 3 - loop
    y_other = hist[f"y{o}"][after]
    m = loop_metrics(t[after], hist[f"y{i}"][after], hist[f"ref{i}"][after])
    return StepCheck(loop, m, float(np.max(np.abs(y_other - y_other[0]))), duration)
