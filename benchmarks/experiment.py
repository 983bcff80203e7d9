"""The benchmark experiment, shared by the scripts and a test: P-, decentralized PI
(3.0, 30) and (2.7, 40), PRBS references around the steady state of 3 V / 3 V,
sampled at 1 s, started in Automatic with the controllers at rest on that state."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Mapping

import numpy as np

from quadtank_tui.core.parameters import PRESET, ControlMode
from quadtank_tui.core.plants.johansson import P_MINUS, levels_to_normalized, steady_state_levels
from quadtank_tui.engine.commands import SetParams, SetState
from quadtank_tui.engine.runner import build_engine

PLANT = P_MINUS.params
U0 = (0.3, 0.3)
H0 = steady_state_levels((10 * U0[0], 10 * U0[1]), PLANT)
Y0 = tuple(levels_to_normalized(H0[:2], PLANT))
PI = (PRESET.controllers[0].pid, PRESET.controllers[3].pid)
AMPLITUDE = 0.03
PERIOD = 20  # samples between possible PRBS changes


def run_engine(seed: int, samples: int = 3600) -> Mapping[str, np.ndarray]:
    """The experiment on the engine (manual clock, no thread); its history."""
    with tempfile.TemporaryDirectory() as tmp:
        e = build_engine(clock="manual", seed=seed, params_dir=Path(tmp), logs_dir=Path(tmp),
                         history_capacity=max(samples, 5000))
        values: dict[str, float | str] = {"SAMPLING TIME.TSamp": 1000}
        for sec, mean in zip(("REFERENCE ONE", "REFERENCE TWO"), Y0):
            values.update({f"{sec}.Wave": "PRBS", f"{sec}.Period": PERIOD, f"{sec}.Amplitude": AMPLITUDE,
                           f"{sec}.On": 1, f"{sec}.Mean": mean})
        assert e.submit(SetParams(values)).result().ok
        e.loop.place_at_steady_state(H0)
        e.loop.set_initial_mode(ControlMode.AUTOMATIC)
        e.loop.matrix.track(Y0, Y0, U0)  # as if it had held u0 in Manual
        e.submit(SetState("Run"))
        e.run_for(float(samples))
        hist = e.history()
        e.stop()
    return hist


def references(hist: Mapping[str, np.ndarray]) -> np.ndarray:
    """(K, 2) references of an engine run."""
    return np.stack([hist["ref1"], hist["ref2"]], axis=1)
