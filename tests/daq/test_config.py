"""The DAQ configuration: the LabJack preset against the vendor's map, the shipped
examples, and garbage refused with file, line and key."""

from __future__ import annotations

from pathlib import Path

import pytest

from quadtank_tui.daq.config import DaqConfigError, load_daq_config, parse_daq_config
from quadtank_tui.daq.registers import Register

ROOT = Path(__file__).parents[2]


def test_labjack_preset_matches_the_t_series_modbus_map() -> None:
    """Numbers from LabJack's T-Series Datasheet, 3.1 Modbus Map
    (https://labjack.com/support/software/api/modbus/modbus-map and its printable
    version, generated from ljm_constants.json):

    - "AIN#(0:13)  Returns the voltage of the specified analog input.  0  FLOAT32  R":
      AIN0 starts at address 0, each FLOAT32 takes 2 registers, so AINn is at 2n;
    - "DAC#(0:1)  ...  1000  FLOAT32  R/W": DAC0 at 1000, DAC1 at 1002;
    - "Zero-Based Addressing" (the address in the map is the address in the packet),
      "Big-Endian" (high word first), "Single Overlapping Map of Addresses" (one map,
      readable with function code 3 or 4);
    - the DACs span 0..5 V (T-Series Datasheet 13.0 DAC; the T7's "DAC0 is 0-5V").
    And the wiring of Table 1, Nunes 1998 appendix A.2: in 0..3 = tanks 1..4,
    out 0 = pump 1, out 1 = pump 2.
    """
    c = load_daq_config("labjack")
    assert c.port == 502
    for i in range(4):
        assert c.inputs[f"AIN{i}"] == Register("input", 2 * i, "float32", "big")
        assert c.tank_register(i + 1) == c.inputs[f"AIN{i}"]
    for i in range(2):
        out = c.outputs[f"DAC{i}"]
        assert out.register == Register("holding", 1000 + 2 * i, "float32", "big")
        assert out.limits == (0.0, 5.0)
        assert c.pump_output(i + 1) is out
    assert (c.interlock_enabled, c.interlock_limit, c.tank_height) == (True, 0.95, 20.0)


def test_shipped_examples_load() -> None:
    lab = load_daq_config(ROOT / "params" / "daq-labjack.yaml")
    assert lab.pumps[0].gain == 2.0 and lab.outputs["DAC0"].limits == (0.0, 5.0)
    rig = load_daq_config(ROOT / "params" / "virtual-rig.yaml")
    assert (rig.host, rig.port) == ("127.0.0.1", 5020)
    assert rig.outputs["DAC1"].limits == (0.0, 10.0)
    assert all(s.gain == 2.0 and s.offset == 0.0 for s in rig.sensors)


def test_a_plc_map_of_its_own_with_scaled_integers() -> None:
    c = load_daq_config(ROOT / "params" / "daq-plc-example.yaml")
    assert c.tank_register(3) == Register("holding", 104, "int16", "big", 0.001)
    assert c.pump_output(2).register == Register("holding", 210, "uint16", "big", 0.001)
    assert c.pump_output(2).limits == (0.0, 10.0)
    assert c.sensors[0].gain == 2.0


def test_a_file_overrides_one_key_of_the_preset() -> None:
    c = parse_daq_config("host: 10.0.0.5\ninputs:\n  AIN2: {address: 8}\n", name="x.yaml")
    assert c.inputs["AIN2"].address == 8 and c.inputs["AIN2"].type == "float32"
    assert c.inputs["AIN0"].address == 0


@pytest.mark.parametrize(
    ("text", "line", "key", "reason"),
    [
        ("port: fivehundred\n", 1, "port", "whole number"),
        ("host: x\nport: 70000\n", 2, "port", "1..65535"),
        ("hots: 10.0.0.1\n", 1, "hots", "unknown key"),
        ("inputs:\n  AIN0: {address: -3}\n", 2, "inputs.AIN0.address", "0..65534"),
        ("inputs:\n  AIN0: {type: double}\n", 2, "inputs.AIN0.type", "float32, int16, uint16"),
        ("inputs:\n  AIN1: {address: 0}\n", 2, "inputs.AIN1.address", "also used by inputs.AIN0"),
        ("outputs:\n  DAC0:\n    limits: [5, 0]\n", 3, "outputs.DAC0.limits", "below high"),
        ("outputs:\n  DAC0: {table: input}\n", 2, "outputs.DAC0.table", "holding"),
        ("channels:\n  tank3: AIN7\n", 2, "channels.tank3", "not one of the inputs"),
        ("channels:\n  tank2: AIN0\n", 2, "channels.tank2", "already wired to tank1"),
        ("calibration:\n  tank4: {gain: 0}\n", 2, "calibration.tank4.gain", "must not be 0"),
        ("calibration:\n  tank4: {gain: .nan}\n", 2, "calibration.tank4.gain", "must be a number"),
        ("interlock:\n  limit: 1.5\n", 2, "interlock.limit", "<= 1"),
        ("interlock:\n  enabled: maybe\n", 2, "interlock.enabled", "true or false"),
        ("timeout: 0\n", 1, "timeout", "> 0"),
        ("preset: siemens\n", 1, "preset", "unknown preset"),
    ],
)
def test_garbage_is_refused_naming_file_line_and_key(
    tmp_path: Path, text: str, line: int, key: str, reason: str
) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(DaqConfigError) as err:
        load_daq_config(path)
    assert (err.value.file, err.value.line, err.value.key) == (str(path), line, key)
    assert reason in err.value.reason
    assert str(err.value).startswith(f"{path}:{line}: {key}: ")


@pytest.mark.parametrize(
    ("text", "reason"),
    [("host: [unclosed\n", "not valid YAML"), ("- just\n- a list\n", "must be a mapping"),
     ("\x00\x01binary", "not valid YAML")],
)
def test_not_a_configuration_at_all(tmp_path: Path, text: str, reason: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(DaqConfigError) as err:
        load_daq_config(path)
    assert str(err.value).startswith(str(path)) and reason in str(err.value)


def test_missing_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(DaqConfigError, match="nope.yaml: no such file"):
        load_daq_config(tmp_path / "nope.yaml")


def test_garbage_config_through_the_cli_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from quadtank_tui.cli import main

    path = tmp_path / "rig.yaml"
    path.write_text("channels:\n  pump1: DAC7\n")
    assert main(["rig", "--map", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"quadtank: error: {path}:2: channels.pump1: 'DAC7' is not one of the outputs (DAC0, DAC1)"


def test_plausible_ranges_default_from_the_tank_height_or_come_from_the_file() -> None:
    c = load_daq_config("labjack")
    assert [c.plausible_range(t) for t in (1, 4)] == [(-2.0, 22.0), (-2.0, 22.0)]
    c = parse_daq_config("interlock: {tank_height: 30}\nplausible:\n  margin: 0.2\n  tank3: [-1, 25.5]\n")
    assert [c.plausible_range(t) for t in (1, 2, 3, 4)] == [(-6.0, 36.0), (-6.0, 36.0), (-1.0, 25.5), (-6.0, 36.0)]


@pytest.mark.parametrize("text, message", [
    ("plausible:\n  tank2: [5, 1]\n", "f.yaml:2: plausible.tank2: low (5) must be below high (1)"),
    ("plausible:\n  tank5: [0, 20]\n", "f.yaml:2: plausible.tank5: tank5 is extra: a quadtank plant has 4 level channels "
     "(tank1, tank2, tank3, tank4) and 2 pump channels (pump1, pump2)"),
    ("plausible:\n  margin: 2\n", "f.yaml:2: plausible.margin: must be <= 1, got 2"),
    ("plausible:\n  tank1: 20\n", "f.yaml:2: plausible.tank1: must be [low, high] in cm, got 20"),
    ("plausible:\n  tank1: [0, .nan]\n", "f.yaml:2: plausible.tank1.1: must be a number, got nan"),
])
def test_bad_plausible_ranges_are_refused_with_file_line_and_key(text: str, message: str) -> None:
    with pytest.raises(DaqConfigError) as err:
        parse_daq_config(text, name="f.yaml")
    assert str(err.value) == message
