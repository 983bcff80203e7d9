"""The virtual rig with another plant and with faults, so the Active path sees them
too (issue 14).  Injected clock: no sockets, no sleeping."""

from __future__ import annotations

import pytest

from quadtank_tui.core import faults as fx
from quadtank_tui.core.faults import Fault
from quadtank_tui.core.plants.johansson import P_MINUS, steady_state_levels
from quadtank_tui.core.plants import CoupledCascade, QuadTank
from quadtank_tui.commands.daq import parse_fault
from quadtank_tui.daq.config import DaqConfigError, load_daq_config
from quadtank_tui.daq.registers import decode, encode
from quadtank_tui.daq.rig import VirtualRig, describe
from quadtank_tui.daq.server import IllegalAddress

CONFIG = load_daq_config("labjack")


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def read_volts(rig: VirtualRig) -> list[float]:
    words = rig.read(0, 8)
    return [decode(CONFIG.inputs[f"AIN{i}"], words[2 * i:2 * i + 2]) for i in range(4)]


def write_volts(rig: VirtualRig, v1: float, v2: float) -> None:
    dac = CONFIG.outputs["DAC0"].register
    rig.write(dac.address, encode(dac, v1) + encode(CONFIG.outputs["DAC1"].register, v2))


def test_cascade_on_the_rig() -> None:
    """Sensor volts kc_i x_i on the two level inputs the cascade has (tank 3, 4's
    registers do not exist); one pump output; the DAQ's 0..10 V span the Quanser
    amplifier's 0..22 V."""
    clock = FakeClock()
    p = CoupledCascade()
    config = load_daq_config("labjack", p)
    rig = VirtualRig(config, p, (15.0, 14.7), clock=clock, watchdog=0)
    words = rig.read(0, 4)
    v = [decode(config.inputs[f"AIN{i}"], words[2 * i:2 * i + 2]) for i in range(2)]
    assert v == pytest.approx([15.0 * p.kc1, 14.7 * p.kc2], abs=1e-5)
    with pytest.raises(IllegalAddress):
        rig.read(4, 2)  # AIN2: no tank 3 on this rig
    dac = config.outputs["DAC0"].register
    with pytest.raises(IllegalAddress):
        rig.write(1002, encode(dac, 1.0))  # DAC1: no pump 2
    rig.write(dac.address, encode(dac, 5.0))
    assert rig.pump_volts == (5.0,)
    clock.now += 30.0
    rig.tick()
    assert rig.h == pytest.approx(p.advance((15.0, 14.7), (11.0,), 30.0), abs=1e-9)
    assert "cm" in rig.status() and rig.plant is None and "pumps=[5.00] V" in rig.status()
    assert describe(config) == "tank1=AIN0@0 tank2=AIN1@2 pump1=DAC0@1000"


def test_a_quadruple_tank_map_is_refused_for_the_cascade() -> None:
    with pytest.raises(DaqConfigError, match="wired for the quadtank plant, but the plant in use is "
                       r"coupled-cascade: a coupled-cascade plant has 2 level channels \(tank1, tank2\)"):
        VirtualRig(CONFIG, CoupledCascade(), (15.0, 14.7), watchdog=0)


def test_a_leak_at_the_rig() -> None:
    clock = FakeClock()
    h0 = steady_state_levels((3.0, 3.0), P_MINUS.params)
    rig = VirtualRig(CONFIG, P_MINUS.params, h0, clock=clock, watchdog=0)
    write_volts(rig, 3.0, 3.0)
    rig.set_fault(Fault("leak", 1, 0.02))
    clock.now += 50.0
    rig.tick()
    expected = fx.advance(QuadTank(P_MINUS.params), rig.faults, h0, (3.0, 3.0), 50.0)
    assert rig.h == pytest.approx(expected, abs=1e-9)
    assert rig.h[0] < h0[0] - 1.0
    assert "faults: leak tank 1 (0.02)" in rig.status()


def test_a_stuck_sensor_at_the_rig() -> None:
    clock = FakeClock()
    rig = VirtualRig(CONFIG, P_MINUS.params, P_MINUS.op.x, clock=clock, watchdog=0)
    before = read_volts(rig)
    rig.set_fault(Fault("sensor_stuck", 1))
    clock.now += 100.0  # pumps off: the tanks drain, sensor 1 does not say so
    after = read_volts(rig)
    assert after[0] == pytest.approx(before[0], abs=1e-5) and after[1] < before[1] - 0.5


@pytest.mark.parametrize("text, parsed", [("leak:1:0.02", ("leak", 1, 0.02)), ("sensor_stuck:2", ("sensor_stuck", 2, 0.0))])
def test_fault_option(text: str, parsed: tuple) -> None:
    assert parse_fault(text) == parsed


@pytest.mark.parametrize("text", ["leak", "leak:x", "leak:1:2:3", "leak:1:abc"])
def test_bad_fault_option(text: str) -> None:
    with pytest.raises(ValueError, match="--fault"):
        parse_fault(text)
