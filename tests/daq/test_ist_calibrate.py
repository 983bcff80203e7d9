"""The steady-state calibration procedure (daq/calibrate.py) on the virtual IST
device: the fit of h against the sensors' ratios r gives back each sensor's dh_dr
and h0, and with the plant the outlet areas."""

from __future__ import annotations

import threading

import pytest

from quadtank_tui.core.plants.johansson import steady_state_levels
from quadtank_tui.core.calibration.procedure import SettleRule
from quadtank_tui.daq.calibrate import fit_pairs, run_procedure
from quadtank_tui.daq.ist import protocol as p
from quadtank_tui.daq.ist.backend import IstBackend
from quadtank_tui.commands.daq_ist import format_ist_result
from quadtank_tui.daq.ist.plant import IST_PLANT, IST_VOLTS
from quadtank_tui.daq.ist.config import IstConfig
from quadtank_tui.daq.ist.device import Firmware, PtyDevice, serve

pytestmark = pytest.mark.wallclock  # the device in real time, x3000


def test_the_procedure_fits_the_sensors_ratio_law_and_the_outlets() -> None:
    fw = Firmware(IstConfig(port=""), IST_PLANT, steady_state_levels(IST_VOLTS, IST_PLANT), speed=3000.0,
                  reset_s=0.0)
    device = PtyDevice(fw)
    stop = threading.Event()
    server = threading.Thread(target=serve, args=(device,), kwargs={"stop": stop.is_set}, daemon=True)
    server.start()
    backend = IstBackend(IstConfig(port=device.path, open_wait=0.05))
    try:
        # the operator reads the scales: the device's true levels
        pairs = run_procedure(backend, [4.0, 6.0, 8.0], SettleRule(window=10, tol=2e-4, timeout=20.0),
                              lambda volts, settled: list(fw.h), poll=0.02)
    finally:
        backend.close()
        stop.set()
        server.join(2.0)
        device.close()
    assert fw.pwm == (0, 0, 0, 0)  # the procedure ends with the pumps stopped
    result = fit_pairs(pairs, IST_PLANT)
    for i in range(1, 5):  # the ADS1115's codes: ~0.005 cm
        cal = result.sensors[i]
        assert cal.gain == pytest.approx(p.DH_DR[i - 1], rel=2e-3)
        assert cal.offset == pytest.approx(p.H0[i - 1], abs=0.05)
        assert cal.rms < 0.01
    assert result.outlets is not None
    # the pumps ran at the PWM of each voltage, whose flow is the nominal one to a PWM step (~1 %)
    assert result.outlets.coefficients == pytest.approx(p.OUTLET_AREAS, rel=0.03)
    text = format_ist_result(result, IST_PLANT)
    assert text.splitlines()[1].startswith("  tank1: {dh_dr: -37.")
