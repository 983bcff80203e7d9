"""`quadtank daq calibrate`: the steady-state procedure on the virtual rig recovers a
sensor gain and offset it was given; pairs from a file reproduce Desautel's Table 1."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Callable

import pytest


from quadtank_tui.cli import main
from quadtank_tui.core.parameters import PRESET
from quadtank_tui.core.plant import steady_state_levels
from quadtank_tui.daq.calibrate import Pairs, fit_pairs, parse_pairs
from quadtank_tui.files.par import write_par

ROOT = Path(__file__).parents[2]
TABLE_1 = """# Desautel Table 1 (coupled tanks: one pump)
u1  volts1 level1 volts2 level2
4   0.5864 3.5    0.2892 3.25
5   1.3422 7.5    1.0359 7.25
6   2.2396 12.25  1.9148 12
7   3.2051 17.75  2.8947 17.75
"""


def test_pairs_from_a_file_give_desautels_table_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "table1.txt"
    path.write_text(TABLE_1)
    assert main(["daq", "calibrate", "--pairs", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    # his g1 5.4310, b1 0.2391, g2 5.5558, b2 1.5420 (his last digits round differently)
    assert out[0] == "tank 1  gain 5.4310 cm/V  offset +0.2390 cm  rms residual 0.101 cm"
    assert out[1] == "tank 2  gain 5.5557 cm/V  offset +1.5419 cm  rms residual 0.123 cm"
    assert out[3:] == ["  tank1: {gain: 5.4310, offset: 0.2390}", "  tank2: {gain: 5.5557, offset: 1.5419}"]


@pytest.mark.parametrize(("text", "message"), [
    ("u1 volts1 level9\n1 2 3\n", "line 1: unknown column 'level9'"),
    ("u1 volts1 level1\n1 2\n", "line 2: 2 values for 3 columns"),
    ("u1 volts1 level1\n1 2 x\n", "line 2: not a number"),
    ("u1 volts1\n1 2\n", "no tank has both"),
    ("# nothing\n", "no header and rows"),
])
def test_a_bad_pairs_file_says_where(text: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        parse_pairs(text, "p.txt")


def test_the_pairs_round_trip_and_give_the_outlets() -> None:
    p = PRESET.plant()
    pairs = Pairs()
    for v in (2.0, 2.5, 3.0):
        h = steady_state_levels((v, v), p)
        pairs.add({"u1": v, "u2": v, **{f"volts{i + 1}": p.kc * h[i] + 0.1 for i in range(4)},
                   **{f"level{i + 1}": h[i] for i in range(4)}})
    again = parse_pairs(pairs.format())
    for k, col in pairs.columns.items():
        assert again.columns[k] == pytest.approx(col, rel=1e-5)
    r = fit_pairs(pairs, p)
    assert r.outlets is not None
    assert r.outlets.coefficients == pytest.approx((p.a1, p.a2, p.a3, p.a4), rel=1e-9)
    for cal in r.sensors.values():
        assert (cal.gain, cal.offset) == pytest.approx((1 / p.kc, -0.1 / p.kc), abs=1e-9)


def test_on_the_virtual_rig_it_recovers_the_sensor_gain_and_offset(
        rig: Callable, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """The rig's sensors read V = 0.45 h + 0.1 (a gain and an offset unlike the
    configuration's 2 cm/V, 0 cm): the fit must find 1/0.45 cm/V and -0.1/0.45 cm.
    The operator's scale readings are the model's steady levels."""
    params = PRESET.with_values({"SIMULATION.Sensor": 0.45})
    par = write_par(tmp_path / "kc045.par", params)
    r = rig("--par", str(par), "--offset", "0.1", "--speed", "4000")
    config = tmp_path / "rig.yaml"
    config.write_text((ROOT / "params" / "virtual-rig.yaml").read_text().replace("port: 5020", f"port: {r.port}"))
    volts = (2.0, 2.5, 3.0)
    heights = [steady_state_levels((v, v), params.plant()) for v in volts]
    monkeypatch.setattr("sys.stdin", io.StringIO("".join(" ".join(f"{x:.6f}" for x in h) + "\n" for h in heights)))
    assert main(["daq", "calibrate", str(config), "--volts", *map(str, volts), "--par", str(par),
                 "--poll", "0.01", "--window", "20", "--tol", "0.0003", "--timeout", "30"]) == 0
    out = capsys.readouterr().out
    assert r.dacs() == (0.0, 0.0)  # the pumps were stopped at the end
    fits = [ln.split() for ln in out.splitlines() if ln.startswith("tank ")]
    assert len(fits) == 4, out
    for f in fits:
        assert float(f[3]) == pytest.approx(1 / 0.45, rel=2e-3), out
        assert float(f[6]) == pytest.approx(-0.1 / 0.45, abs=0.02), out
    assert "u1 u2 volts1 volts2 volts3 volts4 level1 level2 level3 level4" in out


def test_write_puts_the_fit_into_the_daq_file_keeping_its_comments(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    from quadtank_tui.daq.config import load_daq_config

    pairs = tmp_path / "table1.txt"
    pairs.write_text(TABLE_1)
    config = tmp_path / "rig.yaml"
    original = (ROOT / "params" / "virtual-rig.yaml").read_text()
    config.write_text(original)
    monkeypatch.setattr("sys.stdin", io.StringIO("n\n"))
    assert main(["daq", "calibrate", "--pairs", str(pairs), "--write", str(config)]) == 0
    assert config.read_text() == original and "left as it was" in capsys.readouterr().err
    monkeypatch.setattr("sys.stdin", io.StringIO("y\n"))
    assert main(["daq", "calibrate", "--pairs", str(pairs), "--write", str(config)]) == 0
    text = config.read_text()
    assert "  tank1: {gain: 5.43096, offset: 0.238976}\n  tank2: {gain: 5.55574, offset: 1.54193}\n" in text
    assert text.replace("tank1: {gain: 5.43096, offset: 0.238976}", "tank1: {gain: 2.0, offset: 0.0}").replace(
        "tank2: {gain: 5.55574, offset: 1.54193}", "tank2: {gain: 2.0, offset: 0.0}") == original
    sensors = load_daq_config(config).sensors
    assert (sensors[0].gain, sensors[1].offset, sensors[2].gain) == (5.43096, 1.54193, 2.0)


def test_a_daq_file_without_a_calibration_section_gets_one() -> None:
    from quadtank_tui.core.calibration import SensorCalibration
    from quadtank_tui.daq.calibrate import with_calibration
    from quadtank_tui.daq.config import parse_daq_config

    text = with_calibration("preset: labjack\nhost: 10.0.0.2  # the lab's\n",
                            {1: SensorCalibration(2.1, -0.3), 3: SensorCalibration(1.9, 0.25)})
    assert text == ("preset: labjack\nhost: 10.0.0.2  # the lab's\n\ncalibration:\n"
                    "  tank1: {gain: 2.1, offset: -0.3}\n  tank3: {gain: 1.9, offset: 0.25}\n")
    c = parse_daq_config(text)
    assert (c.sensors[0].gain, c.sensors[0].offset, c.sensors[2].offset) == (2.1, -0.3, 0.25)
