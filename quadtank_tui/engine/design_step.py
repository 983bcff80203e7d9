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

from quadtank_tui.core.design.apply import controller_values, one_pump_values
from quadtank_tui.core.design.pid_tuning import PIDTuning
from quadtank_tui.core.metrics import LoopMetrics, loop_metrics
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.engine.commands import SetControlMode, SetParams, SetState
from quadtank_tui.engine.headless import must
from quadtank_tui.engine.history import DEFAULT_CAPACITY
from quadtank_tui.engine.runner import Engine, build_engine, load_parameters
from quadtank_tui.files.par import ParStore

STEP = 0.1  # normalized: 1 V, about 2 cm
SETTLE_BEFORE = 200.0  # s in Manual before Automatic
AUTO_BEFORE_STEP = 10.0  # s in Automatic before the step

@dataclass(frozen=True)
class StepCheck:
    loop: int
    step: LoopMetrics  # of the stepped loop, from the step on
    other_peak: float  # largest |y_other - y_other(step)|, normalized
    duration: float
    u: np.ndarray  # both pumps from the step on, normalized (samples x 2)
    t: np.ndarray  # s from the step
    y: np.ndarray  # the stepped loop's level from the step on, normalized


def run_step(pair: Sequence[PIDTuning], *, par: str | Path | None = None, loop: int = 1,
             duration: float = 600.0, params_dir: Path = Path("params"),
             logs_dir: Path = Path("logs"), tsamp_ms: float | None = None,
             inputs: Sequence[float] | None = None, settle: float = SETTLE_BEFORE) -> StepCheck:
    """Step reference `loop` by STEP with the pair running; figures after the step.
    The engine samples at `tsamp_ms` (None: the parameters' own TSamp).  `inputs`
    (0..1 of each pump's full scale): the Manual pumps before the step, e.g. an
    identification experiment's rest (None: those holding the operating levels),
    for `settle` s.  A one-pump plant's loop (the cascade) is its controlled level on
    reference 2 with the pump u1 (core.design.apply.one_pump_values)."""
    params, _ = load_parameters(par, ParStore(params_dir))
    plant = params.process_plant()  # the plant in use: its pumps hold its operating levels
    if inputs is None:
        levels = params.process_levels()
        op = plant.steady_inputs([x if i in plant.controlled else None for i, x in enumerate(levels)])
        inputs = [u / s.full_scale for u, s in zip(op.u, plant.inputs)]
    v = [float(u) * FULL_SCALE_V for u in inputs] + [0.0] * (2 - len(inputs))
    one_pump = len(plant.inputs) == 1
    tsamp = params.tsamp_ms if tsamp_ms is None else tsamp_ms
    rows = int((settle + AUTO_BEFORE_STEP + duration) / (tsamp / 1000.0)) + 100
    engine: Engine = build_engine(par, clock="manual", params_dir=params_dir,
                                  logs_dir=logs_dir,
                                  history_capacity=max(DEFAULT_CAPACITY, rows))
    try:
        setup = {"SAMPLING TIME.TSamp": tsamp,
                 **(one_pump_values(pair[0]) if one_pump else controller_values(pair))}
        for i, sec in ((0, "REFERENCE ONE"), (1, "REFERENCE TWO")):
            setup.update({f"{sec}.Mean": v[i] / FULL_SCALE_V, f"{sec}.On": 0})
        for command in (SetControlMode("Manual"), SetParams(setup), SetState("Run")):
            must(engine.submit(command).result())
        engine.run_for(settle)
        must(engine.submit(SetControlMode("Automatic")).result())
        engine.run_for(AUTO_BEFORE_STEP)  # as the sample session: the step 10 s later
        ref = 2 if one_pump else loop  # the cascade's loop: error 2 (y2) drives pump 1
        key = f"REFERENCE {'ONE' if ref == 1 else 'TWO'}.Mean"
        mean = engine.snapshot().params.get(key)
        must(engine.submit(SetParams({key: mean + STEP})).result())
        engine.run_for(duration)
        hist = engine.history()
    finally:
        engine.stop()
    t = hist["t"]
    after = t >= settle - 1e-9
    i, o = ref, 3 - ref
    y_other = hist[f"y{o}"][after]
    m = loop_metrics(t[after], hist[f"y{i}"][after], hist[f"ref{i}"][after])
    stepped = t >= (m.step_time if m.step_time is not None else settle) - 1e-9
    u = np.column_stack([hist["u1"][stepped], hist["u2"][stepped]])
    return StepCheck(loop, m, float(np.max(np.abs(y_other - y_other[0]))), duration, u,
                     t[stepped] - t[stepped][0], hist[f"y{i}"][stepped])
