"""The physical fit on a rig that is not our simulator: the cascaded-tanks generator
of foreign_rigs.py (laminar outlets, an upper tank of another size that spills, a
sensor with an offset that saturates at 10 V, noise, 12-bit readings).  The full
default fit of 1024 rows with its multi-start is benchmarks/identify.py's (about
25 s of CPU: too long for the suite); here the pieces it relies on, and the rig's
constants restated in the model's units, whose simulation must match the rig."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from quadtank_tui.core.identify.physical import Experiment, _fit_sensor_scale
from quadtank_tui.core.identify.physical_auto import saturated_outputs
from quadtank_tui.core.plants import CoupledCascade

sys.path.insert(0, str(Path(__file__).parent))
from foreign_rigs import Cascade, cascaded_tanks  # noqa: E402  (a generator beside the tests, no package)

RIG = Cascade()


def record(seed: int, rows: int) -> Experiment:
    u, y = cascaded_tanks(seed, rows=rows)
    return Experiment(f"rig{seed}", 4.0, u[:, None], y[:, None], (1,))


def model_of(rig: Cascade, kc2: float) -> CoupledCascade:
    """The rig in the cascade's units: levels in cm of tank 2 read by kc2, tank 1's
    brim at the model's 30 cm, flows in cm/s of tank 2's level."""
    c2, c1 = rig.kc / kc2, 30.0 / rig.h1max
    return CoupledCascade(alpha1=c2 * rig.a1 / (rig.A2 * math.sqrt(c1)), alpha2=rig.a2 * math.sqrt(c2) / rig.A2,
                          beta1=c2 * rig.k / rig.A2, lam1=c2 * rig.lam1 / (rig.A2 * c1), lam2=rig.lam2 / rig.A2,
                          area1=c2 * rig.A1 / (rig.A2 * c1), spill1=rig.spill, kc2=kc2, ysat2=10.0)


def test_the_records_saturate_and_the_sensor_scale_is_taken_from_them() -> None:
    est = record(1, 1024)
    assert saturated_outputs([est]) == [1]
    notes: list[str] = []
    plant = _fit_sensor_scale(CoupledCascade(), [est], ("alpha1", "alpha2", "beta1"), notes)
    assert plant.values()["kc2"] == pytest.approx(float(est.y.max()) / (0.7 * 30.0))
    assert notes and notes[0].startswith("kc2 0.179992 -> ")


def test_the_rig_restated_in_the_models_units_is_the_rig() -> None:
    """The model family holds the rig: its constants mapped to the cascade's units
    (another sensor scale, another upper tank) simulate the record to its noise."""
    from quadtank_tui.core.identify.physical import estimate_initial, predict

    est = record(1, 256)
    model = model_of(RIG, 10.0 / 21.0).with_values(off2=RIG.offset)
    x0 = estimate_initial(model, est, [], rows=40)
    rms = float(np.sqrt(np.mean((predict(model, est, x0, None) - est.y) ** 2)))
    assert rms < 3 * RIG.noise
