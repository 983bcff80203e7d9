"""Active mode end to end: the engine drives a virtual rig in a subprocess over
Modbus TCP on loopback, and what it logs matches a Simul run of the same setting.

The rig runs at x10 and the engine's clock is paced at the same x10, so three
minutes of process time take about eighteen seconds (at x20, 5 ms a sample, a
loaded 2-core machine missed a tenth of the slots); the Simul run is unpaced.  The
comparison allows the rig's configured sensor noise (plus what it does to the
controllers), not a wall-clock coincidence.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from quadtank_tui.core.plant import FULL_SCALE_V
from quadtank_tui.daq.modbus import ModbusBackend
from quadtank_tui.engine.commands import (
    AddWater, LogOn, LogSave, SetControlMode, SetOperation, SetParams, SetState,
)
from quadtank_tui.engine.runner import Engine, build_engine
from quadtank_tui.files.log import read_log

ROOT = Path(__file__).parents[2]
SPEED = 10.0
DURATION = 180.0           # process seconds
NOISE_V = 0.01             # the rig's sensor noise, V (0.001 normalized)
#: Closed-loop experiment: PI control of y1, y2 with square reference waves about
#: the operating point (means given, so neither run depends on the levels at the switch).
EXPERIMENT = {"REFERENCE ONE.On": 1, "REFERENCE TWO.On": 1,
              "REFERENCE ONE.Mean": 0.60, "REFERENCE TWO.Mean": 0.62,
              "REFERENCE ONE.Period": 60.0, "REFERENCE TWO.Period": 80.0,
              "LOGGING.Points": int(DURATION / 0.1), "LOGGING.Variables": ("t", "y1", "y2", "y3", "y4", "u1", "u2")}


def ok(engine: Engine, command: object) -> None:
    result = engine.submit(command).result()  # type: ignore[arg-type]
    assert result.ok, result.message


def start(engine: Engine) -> None:
    """The same sequence a user does on the Main screen: Automatic, references on,
    LogOn, Run."""
    ok(engine, SetControlMode("Automatic"))
    ok(engine, SetParams(EXPERIMENT))
    ok(engine, LogOn())
    ok(engine, SetState("Run"))


def test_active_on_the_rig_matches_simul(rig: Callable, tmp_path: Path) -> None:
    r = rig("--speed", str(SPEED), "--noise", str(NOISE_V), "--seed", "3")
    active = build_engine(None, daq=ModbusBackend(r.config()), clock="virtual", speed=SPEED,
                          threaded=False, params_dir=ROOT / "params", logs_dir=tmp_path)
    try:
        ok(active, SetOperation("Active"))
        first = active.step()          # a paused Active loop shows the rig's levels
        assert first.operation == "Active" and first.backend == f"modbus 127.0.0.1:{r.port}"
        start(active)
        active.run_for(DURATION)
        snap = active.snapshot()
        assert snap.fault is None and snap.state == "Run" and snap.alarms == ()
        ok(active, LogSave("active"))
    finally:
        active.stop()
    assert r.proc.poll() is None

    a = read_log(tmp_path / "active.log").columns()
    simul = build_engine(None, clock="manual", params_dir=ROOT / "params", logs_dir=tmp_path)
    try:
        # The rig ran (pumps at 0) before the first sample; start the simulation from
        # the levels the rig had at the first logged sample, as a user fills the tanks.
        y_sim = simul.snapshot().y
        for tank in range(4):
            ok(simul, AddWater(tank + 1, float(a[f"y{tank + 1}"][0]) - y_sim[tank]))
        start(simul)
        simul.run_for(DURATION)
        ok(simul, LogSave("simul"))
    finally:
        simul.stop()

    s = read_log(tmp_path / "simul.log").columns()
    assert len(s["y1"]) == int(DURATION / 0.1)
    # Active takes a sample per sampling slot, except the slots a busy machine misses
    # at x20 (5 ms): those went by on the rig too, and the rows carry their true t.
    # Compare each Active row with the Simul row of the same slot.
    slot = np.rint(a["t"] / 0.1).astype(int)
    assert slot[0] == 0 and np.all(np.diff(slot) >= 1) and slot[-1] < len(s["y1"])
    assert len(slot) >= 0.8 * len(s["y1"])
    s = {name: column[slot] for name, column in s.items()}
    # Measured (seed 3, x10, 3-7 missed slots of 1800 at load 7 on 2 cores): max |diff|
    # 3.3-5.1 sigma, RMS 1.02-1.12 sigma, 2-s mean 0.8-2.1 sigma (tank 3, whose start
    # is aligned on one noisy reading; x20 without load: 3.3-5.7, 1.05-1.15, 0.9-2.6).  The
    # bounds leave room for a busy machine's timing, not for a different process.
    # On a machine so loaded that over 5 % of the slots went by (a late sample reads the
    # rig up to a slot later: seen at load 8 on 2 cores, 254 of 1800 missed, max |diff|
    # 10.3 sigma), the bounds double: 16 sigma is 0.016, still a small part of the 0.05
    # (50 sigma) by which the references move the levels (checked below).
    sigma = NOISE_V / FULL_SCALE_V * (2.0 if len(slot) < 0.95 * DURATION / 0.1 else 1.0)
    for name in ("y1", "y2", "y3", "y4"):
        diff = a[name] - s[name]
        assert np.max(np.abs(diff)) < 8 * sigma, name
        assert np.sqrt(np.mean(diff**2)) < 1.5 * sigma, name
        smooth = np.convolve(diff, np.ones(20) / 20, mode="valid")  # 2 s: the noise averaged out
        assert np.max(np.abs(smooth)) < 4 * sigma, name
    # The references really moved the levels (not a comparison of two flat lines).
    assert np.ptp(s["y1"]) > 0.05 and np.ptp(s["y2"]) > 0.05
    for name in ("u1", "u2"):  # PI on noisy measurements: K = 3 times the noise, filtered
        assert np.max(np.abs(a[name] - s[name])) < 0.03, name
