"""Active on the virtual IST device through a pseudo-terminal, end to end: the
engine's PI experiment on params/ist-lisbon.par logs what the same experiment logs
on the simulator, within the rig's quantization.

The device (daq/ist/device.py) is served by a thread on a clock the test moves one
sampling time before each read (as test_active_end_to_end does for Modbus), so the
run does not depend on the machine's load.  What differs from Simul is the rig's
own: the ADS1115's codes (~0.005 cm here) and the pumps' 10-bit PWM through the
identified law (one PWM step is 0.03-0.1 V about the operating point)."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np

from quadtank_tui.daq.ist.backend import IstBackend
from quadtank_tui.daq.ist.config import IstConfig
from quadtank_tui.daq.ist.device import Firmware, PtyDevice, serve
from quadtank_tui.engine.backend import Levels4
from quadtank_tui.engine.commands import SetDisturbance, SetOperation
from quadtank_tui.engine.runner import Engine, build_engine
from quadtank_tui.files.log_reader import read_log
from quadtank_tui.files.par import read_par
from daqkit import active_run, simul_twin, start_experiment

ROOT = Path(__file__).parents[2]
PAR = ROOT / "params" / "ist-lisbon.par"
H = 1.0             # TSamp of params/ist-lisbon.par, s
DURATION = 300.0    # process seconds
EXPERIMENT = {"REFERENCE ONE.On": 1, "REFERENCE TWO.On": 1,
              "REFERENCE ONE.Mean": 0.30, "REFERENCE TWO.Mean": 0.27,
              "REFERENCE ONE.Amplitude": 0.04, "REFERENCE TWO.Amplitude": 0.04,
              "REFERENCE ONE.Period": 120.0, "REFERENCE TWO.Period": 160.0,
              "LOGGING.Points": int(DURATION / H), "LOGGING.Variables": ("t", "y1", "y2", "y3", "y4", "u1", "u2")}


class Lockstep(IstBackend):
    """The IST backend moving the device's clock one sampling time before each read,
    once the device has taken every pump frame sent (its thread reads the pty: a
    frame it took after the clock moved would act one sample late)."""

    def __init__(self, config: IstConfig, clock: list[float], firmware: Firmware) -> None:
        super().__init__(config, clock=lambda: clock[0])
        self.clock, self.firmware, self.reads, self.sent = clock, firmware, 0, 0

    def write_pumps(self, u: tuple[float, float]) -> None:
        super().write_pumps(u)
        self.sent += 1

    def read_levels(self) -> Levels4:
        deadline = time.monotonic() + 2.0
        while self.firmware.frames < self.sent and time.monotonic() < deadline:
            time.sleep(0.0005)
        assert self.firmware.frames == self.sent
        self.clock[0] = self.reads * H
        self.reads += 1
        return super().read_levels()


def start(engine: Engine) -> None:
    start_experiment(engine, EXPERIMENT)


def test_active_on_the_virtual_ist_device_matches_simul(tmp_path: Path) -> None:
    clock = [0.0]
    params = read_par(PAR).params
    firmware = Firmware(IstConfig(port=""), params.quadtank_constants(), params.process_levels(),
                        clock=lambda: clock[0], reset_s=0.0)
    device = PtyDevice(firmware)
    stop = threading.Event()
    server = threading.Thread(target=serve, args=(device,), kwargs={"stop": stop.is_set}, daemon=True)
    server.start()
    backend = Lockstep(IstConfig(port=device.path, open_wait=0.05), clock, firmware)
    active = build_engine(PAR, daq=backend, clock="manual", params_dir=ROOT / "params", logs_dir=tmp_path)
    try:
        active_run(active, f"ist serial {device.path}", start, DURATION)
    finally:
        stop.set()
        server.join(2.0)
        device.close()
    assert firmware.pwm == (0, 0, 0, 0)  # the engine's stop: a whole zero frame
    assert not firmware.hung

    a = read_log(tmp_path / "active.log").columns()
    s = simul_twin(tmp_path / "active.log", start, DURATION, tmp_path, PAR)
    assert len(a["y1"]) == int(DURATION / H)
    assert np.ptp(s["y1"]) > 0.05 and np.ptp(s["y2"]) > 0.05  # the references moved the levels
    # Measured (the same on every run): y max |diff| 0.00026-0.00095 (0.01-0.04 cm at
    # 0.25 V/cm), RMS 0.00009-0.00042, beside swings (ptp) of 0.067-0.12; u max 0.0018,
    # 0.0037 (0.02-0.04 V: about a PWM step), RMS 0.0007, 0.0015.  Bounds: twice those.
    for name in ("y1", "y2", "y3", "y4"):
        diff = a[name] - s[name]
        assert np.max(np.abs(diff)) < 0.002 and np.sqrt(np.mean(diff**2)) < 0.0008, name
    for name in ("u1", "u2"):
        diff = a[name] - s[name]
        assert np.max(np.abs(diff)) < 0.008 and np.sqrt(np.mean(diff**2)) < 0.003, name
    # the PWM really quantized the pumps: the rig's u is not the simulator's to the bit
    assert np.max(np.abs(a["u1"] - s["u1"])) > 1e-4


def test_an_answer_lost_on_the_line_pauses_the_run_within_the_sample_pumps_at_0(tmp_path: Path) -> None:
    params = read_par(PAR).params
    firmware = Firmware(IstConfig(port=""), params.quadtank_constants(), params.process_levels(), reset_s=0.0)
    device = PtyDevice(firmware)
    stop = threading.Event()
    server = threading.Thread(target=serve, args=(device,), kwargs={"stop": stop.is_set}, daemon=True)
    server.start()
    backend = IstBackend(IstConfig(port=device.path, open_wait=0.05, timeout=0.3))
    engine = build_engine(PAR, daq=backend, clock="manual", params_dir=ROOT / "params", logs_dir=tmp_path)
    try:
        assert engine.submit(SetOperation("Active")).result().ok
        start_experiment(engine, {"REFERENCE ONE.On": 1, "REFERENCE TWO.On": 1})
        assert engine.submit(SetDisturbance(1.0, 0.5)).result().ok
        for _ in range(3):
            engine.step()
        time.sleep(0.1)
        assert firmware.pwm[:2] != (0, 0) and firmware.pwm[2:] == (255, 128) and engine.snapshot().fault is None
        firmware.mute = True      # the '$' is heard, its answer never comes
        t0 = time.monotonic()
        snap = engine.step()
        took = time.monotonic() - t0
        assert snap.fault is not None and "no answer within 0.3 s" in snap.fault and snap.state == "Pause"
        assert took < 0.3 + 0.05 + 1.0  # the timeout, the reopening's wait, slack for a loaded machine
        time.sleep(0.1)
        assert firmware.pwm == (0, 0, 0, 0) and not firmware.hung  # reopened (reset) and a zero frame
        assert engine.snapshot().disturbances == (0.0, 0.0)  # the fault stopped the disturbance pumps too
        assert backend.safe_state_error == ""
    finally:
        engine.stop()
        stop.set()
        server.join(2.0)
        device.close()
