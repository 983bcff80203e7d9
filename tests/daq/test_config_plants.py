"""The DAQ configuration follows the plant in use (issue 14): as many level and pump
channels as the plant has, the plant's own sensors by default, and a map of another
plant refused with the file, the line and the extra or missing keys."""

from __future__ import annotations

from pathlib import Path

import pytest

from quadtank_tui.core.plants import CoupledCascade, CoupledTITO, DesautelQTP, QuadTank
from quadtank_tui.daq.config import DaqConfigError, load_daq_config, parse_daq_config

ROOT = Path(__file__).parents[2]
CASCADE = "a coupled-cascade plant has 2 level channels (tank1, tank2) and 1 pump channel (pump1)"


def test_the_preset_for_the_cascade_has_two_levels_and_one_pump() -> None:
    """Desautel's calibrated sensors (2.3): g1 = 5.4310, g2 = 5.5558 cm/V, so an
    ideal sensor reads level = g_i volts; his tanks are 30 cm tall."""
    c = load_daq_config("labjack", CoupledCascade())
    assert c.tanks == ("tank1", "tank2") and c.pump_channels == ("pump1",)
    assert dict(c.channels) == {"tank1": "AIN0", "tank2": "AIN1", "pump1": "DAC0"}
    assert [s.gain for s in c.sensors] == pytest.approx([5.4310, 5.5558], rel=1e-12)
    assert c.sensor_gains == pytest.approx((1 / 5.4310, 1 / 5.5558), rel=1e-12)
    assert c.tank_height == 30.0 and c.plausible_range(2) == pytest.approx((-3.0, 33.0))
    assert c.plant.feeders == ((0,), (0,))  # the one pump fills the lower tank too


def test_the_two_input_rig_in_metres() -> None:
    """Murray-Smith: y = Gd H with Gd = 33.33 V/m, tanks 0.3 m tall, a pump per tank."""
    c = load_daq_config(ROOT / "params" / "virtual-rig-coupled.yaml", CoupledTITO())
    assert c.tanks == ("tank1", "tank2") and c.pump_channels == ("pump1", "pump2")
    assert c.sensors[1].level(3.333) == pytest.approx(0.1, rel=1e-12)
    assert c.sensor_gains == (33.33, 33.33) and c.tank_height == 0.3
    assert c.plant.feeders == ((0,), (1,)) and c.plant.unit == "m"


def test_four_tank_plants_keep_the_four_channels() -> None:
    quad = load_daq_config("labjack", QuadTank())
    assert quad == load_daq_config("labjack")  # the quadruple tank as before
    assert quad.sensor_gains == (0.5,) * 4 and quad.tank_height == 20.0
    qtp = load_daq_config("labjack", DesautelQTP())
    assert qtp.tanks == ("tank1", "tank2", "tank3", "tank4") and qtp.sensor_gains == pytest.approx((1 / 3,) * 4)


def test_a_four_level_map_for_a_two_tank_plant_names_the_extra_keys() -> None:
    """params/virtual-rig.yaml calibrates four tanks and two pumps (line 22: tank3)."""
    path = ROOT / "params" / "virtual-rig.yaml"
    with pytest.raises(DaqConfigError) as err:
        load_daq_config(path, CoupledCascade())
    assert str(err.value) == f"{path}:22: calibration.tank3: tank3, tank4, pump2 are extra: {CASCADE}"
    text = "channels:\n  tank1: AIN0\n  tank2: AIN1\n  tank3: AIN2\n  tank4: AIN3\n  pump1: DAC0\n"
    with pytest.raises(DaqConfigError) as err:
        parse_daq_config(text, name="m.yaml", plant=CoupledTITO())
    assert str(err.value) == ("m.yaml:4: channels.tank3: tank3, tank4 are extra: a coupled-tito plant has "
                              "2 level channels (tank1, tank2) and 2 pump channels (pump1, pump2)")


def test_missing_channels_are_named() -> None:
    text = ("preset: none\nhost: h\nport: 502\ninputs:\n  A: {address: 0}\n  B: {address: 2}\n"
            "outputs:\n  D: {address: 100}\nchannels:\n  tank1: A\n")
    with pytest.raises(DaqConfigError) as err:
        parse_daq_config(text, name="m.yaml", plant=CoupledCascade())
    assert str(err.value) == f"m.yaml:9: channels.tank2: tank2, pump1 missing: {CASCADE}"
    done = parse_daq_config(text + "  tank2: B\n  pump1: D\n", name="m.yaml", plant=CoupledCascade())
    assert done.tank_register(2).address == 2 and done.pump_output(1).register.address == 100


@pytest.mark.parametrize("text, message", [
    ("calibration:\n  sensor_gain: [0.2, 0.2, 0.2]\n",
     "m.yaml:2: calibration.sensor_gain: must be one number or a list of 2 (one per level channel), "
     "got [0.2, 0.2, 0.2]"),
    ("calibration:\n  sensor_gain: [0.2, -1]\n", "m.yaml:2: calibration.sensor_gain.1: must be > 0, got -1"),
    ("plausible:\n  tank2: 3\n", "m.yaml:2: plausible.tank2: must be [low, high] in cm, got 3"),
])
def test_bad_per_tank_values_are_refused(text: str, message: str) -> None:
    with pytest.raises(DaqConfigError) as err:
        parse_daq_config(text, name="m.yaml", plant=CoupledCascade())
    assert str(err.value) == message


def test_a_configuration_read_for_one_plant_refuses_another() -> None:
    c = load_daq_config("labjack")
    with pytest.raises(DaqConfigError) as err:
        c.check_plant(CoupledCascade())
    assert str(err.value) == ("preset labjack: wired for the quadtank plant, but the plant in use is "
                              f"coupled-cascade: {CASCADE}; read the configuration for it")
    c.check_plant(QuadTank())  # no error
