"""The MPC in Active on the virtual rig (issue 26): the same code path as every
controller type, so Active under MPC logs what Simul under MPC logs, within the
rig's sensor noise (the rig's clock moved in lockstep, as test_active_end_to_end).

The MPC's modules (scipy, OSQP) are imported before the run: the first switch to
MPC imports them on the loop's thread, which on a loaded machine took longer than
the rig guard's 1 s watchdog (pumps to 0, an alarm), as a first state feedback does."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.daq.config import load_daq_config
from quadtank_tui.daq.rig import SensorModel, VirtualRig
from quadtank_tui.engine import mpc_control  # noqa: F401 - loaded before the run: see below
from quadtank_tui.engine.runner import Engine, build_engine
from quadtank_tui.files.log_reader import read_log
from daqkit import VIRTUAL_RIG, active_run, simul_twin, start_experiment
from test_active_end_to_end import H, NOISE_V, Lockstep

ROOT = Path(__file__).parents[2]
DURATION = 60.0
EXPERIMENT = {"CONTROL.Type": "MPC", "REFERENCE ONE.On": 1, "REFERENCE ONE.Mean": 0.62,
              "REFERENCE ONE.Amplitude": 0.03, "REFERENCE ONE.Period": 40.0, "REFERENCE TWO.Mean": 0.64,
              "LOGGING.Points": int(DURATION / H), "LOGGING.Variables": ("t", "y1", "y2", "y3", "y4", "u1", "u2")}


def start(engine: Engine) -> None:
    start_experiment(engine, EXPERIMENT)


def test_mpc_in_active_on_the_rig_matches_simul(device: Callable, tmp_path: Path) -> None:
    clock = [0.0]
    model = VirtualRig(load_daq_config(VIRTUAL_RIG, PRESET.process_plant()), PRESET.quadtank_constants(),
                       PRESET.process_levels(), watchdog=0.0, sensors=SensorModel(noise=NOISE_V, seed=3),
                       clock=lambda: clock[0])
    rig = device((0.0,) * 4, bank=model)
    backend = Lockstep(rig.config(), clock)
    active = build_engine(None, daq=backend, clock="manual", params_dir=ROOT / "params", logs_dir=tmp_path)
    active_run(active, f"modbus 127.0.0.1:{rig.port}", start, DURATION)
    info = active.snapshot().mpc
    assert info is not None and info.solves == int(DURATION / H) and info.faults == 0

    a = read_log(tmp_path / "active.log").columns()
    s = simul_twin(tmp_path / "active.log", start, DURATION, tmp_path)
    sigma = NOISE_V / FULL_SCALE_V
    assert np.ptp(s["y1"]) > 0.03  # the square wave moved level 1
    for name in ("y1", "y2"):
        assert np.sqrt(np.mean((a[name] - s[name]) ** 2)) < 3 * sigma, name
    for name in ("u1", "u2"):
        assert np.all((a[name] >= 0.0) & (a[name] <= 1.0)), name
        assert np.sqrt(np.mean((a[name] - s[name]) ** 2)) < 0.03, name
