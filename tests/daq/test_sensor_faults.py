"""A sensor reading no tank can have is a sensor fault, not a level.

A broken wire puts a sensor at the converter's rail (-10.5 V), and a confused
device can answer 1e30 V.  Taken as levels, the controllers act on them (in
Automatic pump 1 went to 10 V and stayed there for a whole run) and the interlock,
reading the same sensor, cannot trip.  Each reading is checked against its tank's
plausible range (DAQ configuration, `plausible:`; by default 10 % of the tank
height below the bottom and above the top): outside it the loop pauses with the
pumps at 0 and the fault names the tank and the channel.  Against a device in this
process whose sensor voltages the test sets (tests/daq/conftest.py).
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.daq.config import parse_daq_config
from quadtank_tui.daq.modbus import ModbusBackend
from quadtank_tui.engine.commands import CommandResult, SetControlMode, SetOperation, SetParams, SetState
from quadtank_tui.engine.runner import Engine, build_engine
from daqkit import rig_yaml

ROOT = Path(__file__).parents[2]
GOOD = (3.0, 3.0, 2.0, 2.0)  # volts: 6, 6, 4, 4 cm with the virtual rig's calibration (2 cm/V)


def ok(result: CommandResult) -> None:
    assert result.ok, result.message


def automatic_on(backend: ModbusBackend, tmp_path: Path) -> Engine:
    """Active, Automatic with references well above the levels: the controllers ask
    for full pumps, as they did with a sensor stuck low."""
    engine = build_engine(None, daq=backend, clock="manual", params_dir=ROOT / "params", logs_dir=tmp_path)
    for command in (SetOperation("Active"), SetState("Run"), SetControlMode("Automatic"),
                    SetParams({"REFERENCE ONE.Mean": 0.8, "REFERENCE TWO.Mean": 0.8})):
        ok(engine.submit(command).result())
    return engine


@pytest.mark.parametrize("tank, volts, said", [
    (1, -10.5, "tank1 (AIN0) reads -10.5 V = -21 cm, outside its plausible -2..22 cm"),
    (3, 1e30, "tank3 (AIN2) reads 1e+30 V = 2e+30 cm, outside its plausible -2..22 cm"),
    (2, 11.5, "tank2 (AIN1) reads 11.5 V = 23 cm, outside its plausible -2..22 cm"),
])
def test_a_reading_outside_the_plausible_range_pauses_with_the_pumps_at_0(
        device: Callable, tmp_path: Path, tank: int, volts: float, said: str) -> None:
    dev = device(GOOD)
    engine = automatic_on(ModbusBackend(dev.config()), tmp_path)
    try:
        engine.step(5)
        snap = engine.snapshot()
        assert snap.state == "Run" and snap.fault is None
        assert min(dev.bank.dacs()) > 5.0                  # the pumps run hard
        bad = list(GOOD)
        bad[tank - 1] = volts
        dev.bank.set_volts(tuple(bad))
        snap = engine.step()
        assert snap.state == "Pause"
        assert snap.fault == f"modbus 127.0.0.1:{dev.port}: sensor fault: {said} (a broken wire or a dead sensor?)"
        assert dev.bank.dacs() == (0.0, 0.0)
        assert snap.y[tank - 1] == pytest.approx(GOOD[tank - 1] / 10)  # the last true level, not the bad one
        snap = engine.step()                                # paused: still a fault, still 0
        assert snap.state == "Pause" and snap.fault is not None and "sensor fault" in snap.fault
        assert dev.bank.dacs() == (0.0, 0.0)
    finally:
        engine.stop()


def test_a_range_of_its_own_from_the_configuration(device: Callable, tmp_path: Path) -> None:
    """`plausible: {tank2: [0, 15]}`: 16 cm in tank 2 is a fault there; tank 1 keeps
    the default range, so 21 cm there is a level."""
    dev = device((10.5, 8.0, 2.0, 2.0))
    text = rig_yaml(dev.port)
    config = parse_daq_config(text + "plausible:\n  tank2: [0, 15]\n", name="rig.yaml")
    backend = ModbusBackend(config)
    try:
        with pytest.raises(Exception) as err:
            backend.read_levels()
        assert "tank2 (AIN1) reads 8 V = 16 cm, outside its plausible 0..15 cm" in str(err.value)
        dev.bank.set_volts((10.5, 7.0, 2.0, 2.0))
        assert backend.read_levels()[0] == pytest.approx(1.05)
    finally:
        backend.close()


def test_daq_check_shows_every_sensor_and_marks_the_faulty_one(device: Callable, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    """Bringing up a rig: the table shows all four readings, the one at the rail
    marked, and the status is 1."""
    from quadtank_tui.cli import main

    dev = device((3.0, -10.5, 2.0, 2.0))
    config = tmp_path / "rig.yaml"
    config.write_text(rig_yaml(dev.port))
    assert main(["daq", "check", str(config)]) == 1
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].split() == ["tank", "1", "AIN0", "3.0000", "V", "6.00", "cm", "y", "=", "0.3000"]
    assert lines[2] == ("tank 2    AIN1  -10.5000 V   -21.00 cm  y = -1.0500"
                        "  SENSOR FAULT: outside its plausible -2..22 cm")
    assert dev.bank.dacs() == (0.0, 0.0)
