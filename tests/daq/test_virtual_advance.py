"""How the two virtual devices (the Modbus rig, the IST Nano on a pty) advance their
tanks between requests: both by the plant's own step, core.faults.advance, which is
the plain model's step, bit for bit, when nothing else acts.  Injected clocks: no
sockets, no sleeping."""

from __future__ import annotations

import pytest

from quadtank_tui.core.plants.johansson import PlantParams, advance
from quadtank_tui.core.plants import QuadTank
from quadtank_tui.daq.config import load_daq_config
from quadtank_tui.daq.ist import protocol as p
from quadtank_tui.daq.ist.plant import IST_PLANT
from quadtank_tui.daq.ist.config import IstConfig
from quadtank_tui.daq.ist.device import Firmware
from quadtank_tui.daq.registers import encode
from quadtank_tui.daq.rig import VirtualRig

LEVELS = (12.0, 11.0, 6.0, 5.0)


def firmware_at(pwm: tuple[int, int, int, int], dt: float) -> tuple[Firmware, tuple[float, ...]]:
    """A Nano with `pwm` on its pins, its tanks after dt s."""
    clock = [0.0]
    fw = Firmware(IstConfig(port=""), IST_PLANT, LEVELS, clock=lambda: clock[0], reset_s=0.0)
    fw.pwm = pwm
    clock[0] = dt
    fw.tick()
    return fw, fw.h


def test_the_nano_tanks_at_full_duty_are_the_plain_models_step_at_12_volts() -> None:
    fw, h = firmware_at((p.PWM_MAX, p.PWM_MAX, 0, 0), 1.5)  # within the 2 s watchdog
    assert fw.volts() == pytest.approx((12.0, 12.0), abs=1e-12)  # above the Lund pumps' 10 V
    assert h == advance(LEVELS, fw.volts(), 1.5, IST_PLANT)


def test_a_disturbance_pump_adds_its_flow_and_changes_nothing_else() -> None:
    """d1 pours q into tank 1: h1 rises by about q dt / A1 more than without it, and
    the pumps keep their 12 V (tanks 3 and 4, which only the pumps feed, are the
    same); before, a disturbance pump switched on cut the pumps to 10 V."""
    dt = 0.2
    fw, with_d = firmware_at((p.PWM_MAX, p.PWM_MAX, 50, 0), dt)
    q1 = fw.disturbance_flows()[0]
    _, without = firmware_at((p.PWM_MAX, p.PWM_MAX, 0, 0), dt)
    assert q1 == pytest.approx(5.03, abs=0.01)
    assert with_d[0] - without[0] == pytest.approx(q1 * dt / IST_PLANT.A1, abs=1e-3)  # 0.034 cm
    assert with_d[1] == pytest.approx(without[1], abs=1e-9)
    assert with_d[2:] == pytest.approx(without[2:], abs=1e-9)


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def rig_after(plant: PlantParams | QuadTank, volts: tuple[float, float], levels: tuple[float, ...],
              dt: float) -> VirtualRig:
    clock = Clock()
    config = load_daq_config("labjack", plant if isinstance(plant, QuadTank) else QuadTank(plant))
    rig = VirtualRig(config, plant, levels, clock=clock)
    words = [w for i, v in enumerate(volts) for w in encode(config.pump_output(i + 1).register, v)]
    rig.write(config.pump_output(1).register.address, words)
    clock.now += dt
    rig.tick()
    return rig


def test_the_rig_steps_the_plain_quadruple_tank_bit_for_bit() -> None:
    rig = rig_after(PlantParams(), (6.0, 5.5), LEVELS, 30.0)
    assert rig.h == advance(LEVELS, rig.pump_volts, 30.0, PlantParams())


def test_the_rig_steps_a_quadruple_tank_with_its_effects() -> None:
    """Pumps below their threshold (vmin 2 V) move no water: empty tanks stay
    empty; before, the rig stepped the plain model unless a fault was on."""
    plant = QuadTank(PlantParams(), vmin1=2.0, vmin2=2.0)
    rig = rig_after(plant, (1.5, 1.5), (0.0, 0.0, 0.0, 0.0), 30.0)
    assert rig.pump_volts == pytest.approx((1.5, 1.5), abs=1e-3)
    assert rig.h == (0.0, 0.0, 0.0, 0.0)
    assert rig.h == plant.advance((0.0,) * 4, rig.pump_volts, 30.0)
    plain = rig_after(PlantParams(), (1.5, 1.5), (0.0, 0.0, 0.0, 0.0), 30.0)
    assert min(plain.h) > 0.1  # what the plain model does with 1.5 V
