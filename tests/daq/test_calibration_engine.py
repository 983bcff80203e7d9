"""The calibration procedure through the engine's commands on the virtual rig
(Desautel 2.3): the loop holds the pumps sample by sample, waits for the heights,
and the pairs it collects recover the rig's sensor gain and offset."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.core.plants.johansson import steady_state_levels
from quadtank_tui.daq.calibrate import Pairs, fit_pairs
from quadtank_tui.daq.modbus import ModbusBackend
from quadtank_tui.engine.commands import (
    Command,
    CalibrationHeights, CancelCalibration, SetOperation, SetState, StartCalibration,
)
from quadtank_tui.engine.runner import Engine, build_engine
from quadtank_tui.files.par import write_par

SENSOR = 0.45   # V/cm on the rig; the configuration says 2 cm/V
OFFSET = 0.1    # V


def ok(engine: Engine, command: Command) -> None:
    result = engine.submit(command).result()
    assert result.ok, result.message


def step_until(engine: Engine, phase: str, seconds: float = 30.0) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        s = engine.step()
        assert s.calibration is not None
        if s.calibration.phase == phase:
            return
        assert s.calibration.phase == "settling", s.calibration
    raise AssertionError(f"no {phase} within {seconds} s: {engine.snapshot().calibration}")


@pytest.fixture
def active(rig: Callable, tmp_path: Path):
    params = PRESET.with_values({"SIMULATION.Sensor": SENSOR})
    par = write_par(tmp_path / "kc045.par", params)
    r = rig("--par", str(par), "--offset", str(OFFSET), "--speed", "4000")
    engine = build_engine(None, daq=ModbusBackend(r.config()), clock="manual",
                          params_dir=tmp_path, logs_dir=tmp_path)
    ok(engine, SetOperation("Active"))
    yield engine, r, params
    engine.stop()


def test_the_engine_runs_the_procedure_and_the_pairs_recover_the_rig_sensors(active) -> None:
    engine, r, params = active
    ok(engine, StartCalibration((2.0, 2.5, 3.0), window=2.0, tol=0.0003, timeout=3600.0))
    refused = engine.submit(SetState("Run")).result()
    assert not refused.ok and "calibration" in refused.message
    for v in (2.0, 2.5, 3.0):
        step_until(engine, "heights")
        s = engine.snapshot()
        assert s.u == (v / 10, v / 10) and s.calibration is not None
        assert s.calibration.volts[s.calibration.step] == v and len(s.calibration.settled) == 4
        ok(engine, CalibrationHeights(tuple(steady_state_levels((v, v), params.quadtank_constants()))))
    engine.step()
    status = engine.snapshot().calibration
    assert status is not None and status.phase == "done" and r.dacs() == (0.0, 0.0)
    result = fit_pairs(Pairs({k: list(v) for k, v in status.columns}), params.quadtank_constants())
    for cal in result.sensors.values():
        assert cal.gain == pytest.approx(1 / SENSOR, rel=2e-3)
        assert cal.offset == pytest.approx(-OFFSET / SENSOR, abs=0.02)
    assert result.outlets is not None
    p = params.quadtank_constants()
    assert result.outlets.coefficients == pytest.approx((p.a1, p.a2, p.a3, p.a4), rel=5e-3)


def test_cancel_puts_the_pumps_to_0_and_simul_refuses(active, poll: Callable) -> None:
    engine, r, _ = active
    ok(engine, StartCalibration((4.0,), window=2.0, tol=1e-9))
    for _ in range(5):
        engine.step()
    assert poll(lambda: r.dacs() == (4.0, 4.0), 30.0)
    ok(engine, CancelCalibration())
    assert r.dacs() == (0.0, 0.0)
    s = engine.step()
    assert s.calibration is not None and s.calibration.phase == "cancelled" and s.u == (0.0, 0.0)
    ok(engine, CancelCalibration())
    assert engine.step().calibration is None
    ok(engine, SetOperation("Simul"))
    refused = engine.submit(StartCalibration((2.0,))).result()
    assert not refused.ok and "Active" in refused.message
