"""`quadtank daq calibrate`: the steady-state procedure on the virtual rig recovers a
sensor gain and offset it was given; pairs from a file reproduce Desautel's Table 1."""

from __future__ import annotations

import io
import subprocess
import sys
import os
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

import pytest


from quadtank_tui.cli import main
from quadtank_tui.core.parameters import PRESET
from quadtank_tui.core.plants.johansson import steady_state_levels
from quadtank_tui.core.calibration.procedure import SettleRule
from quadtank_tui.daq.calibrate import Pairs, fit_pairs, parse_pairs, run_procedure
from quadtank_tui.files.par import write_par
from daqkit import VIRTUAL_RIG, rig_yaml

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


@pytest.mark.parametrize("what", ["/dev/zero", "folder", "fifo", "large"])
def test_pairs_that_are_no_small_regular_file_are_refused_unread(
        what: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 41: `--pairs /dev/zero` grew to 11.9 GB and a MemoryError."""
    path = {"/dev/zero": Path("/dev/zero"), "folder": tmp_path, "fifo": tmp_path / "fifo",
            "large": tmp_path / "large.txt"}[what]
    if what == "fifo":
        os.mkfifo(path)  # opened without blocking, refused from fstat: nobody writes it
    if what == "large":
        path.write_text(TABLE_1)
        os.truncate(path, 50_000_000)  # sparse
    assert main(["daq", "calibrate", "--pairs", str(path)]) == 2
    said = {"/dev/zero": "cannot read: a character device, not a file", "folder": "cannot read: a directory, not a file",
            "fifo": "cannot read: a FIFO (named pipe), not a file",
            "large": "larger than 1,000,000 bytes: not a file of settled pairs"}[what]
    assert capsys.readouterr().err == f"quadtank: error: {path}: {said}\n"


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
    p = PRESET.quadtank_constants()
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
    config.write_text(rig_yaml(r.port))
    volts = (2.0, 2.5, 3.0)
    heights = [steady_state_levels((v, v), params.quadtank_constants()) for v in volts]
    monkeypatch.setattr("sys.stdin", io.StringIO("".join(" ".join(f"{x:.6f}" for x in h) + "\n" for h in heights)))
    par_before, config_before = par.read_text(), config.read_text()
    assert main(["daq", "calibrate", str(config), "--volts", *map(str, volts), "--par", str(par),
                 "--poll", "0.01", "--window", "20", "--tol", "0.0003", "--timeout", "30",
                 "--write", "--yes"]) == 0
    out = capsys.readouterr().out
    assert r.dacs() == (0.0, 0.0)  # the pumps were stopped at the end
    fits = [ln.split() for ln in out.splitlines() if ln.startswith("tank ")]
    assert len(fits) == 4, out
    for f in fits:
        assert float(f[3]) == pytest.approx(1 / 0.45, rel=2e-3), out
        assert float(f[6]) == pytest.approx(-0.1 / 0.45, abs=0.02), out
    assert "u1 u2 volts1 volts2 volts3 volts4 level1 level2 level3 level4" in out
    # --write with no file: CONFIG itself gets the sensors, the .par the outlets
    from quadtank_tui.daq.config import load_daq_config
    from quadtank_tui.files.par import read_par

    for i, (cal, f) in enumerate(zip(load_daq_config(config).sensors, fits)):
        assert (cal.gain, cal.offset) == pytest.approx((float(f[3]), float(f[6])), abs=1e-4), i
    changed = [(a, b) for a, b in zip(config_before.splitlines(), config.read_text().splitlines()) if a != b]
    assert [a.split(":")[0].strip() for a, _ in changed] == ["tank1", "tank2", "tank3", "tank4"]
    written = read_par(par).params.simulation.time_constants
    changed = [(a, b) for a, b in zip(par_before.splitlines(), par.read_text().splitlines()) if a != b]
    assert {a.split()[0] for a, _ in changed} <= {f"TimeConst{i}" for i in range(1, 5)}, changed
    assert written == pytest.approx(params.simulation.time_constants, rel=5e-3)  # the rig is the file's plant


class Terminal(io.StringIO):
    """Typed answers on a terminal (the prompt is asked only on one)."""

    def isatty(self) -> bool:
        return True


def test_write_puts_the_fit_into_the_daq_file_keeping_its_comments(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    from quadtank_tui.daq.config import load_daq_config

    pairs = tmp_path / "table1.txt"
    pairs.write_text(TABLE_1)
    config = tmp_path / "rig.yaml"
    original = (ROOT / "params" / "virtual-rig.yaml").read_text()
    config.write_text(original)
    monkeypatch.setattr("sys.stdin", Terminal("n\n"))
    assert main(["daq", "calibrate", "--pairs", str(pairs), "--write", str(config)]) == 0
    assert config.read_text() == original and "left as they were" in capsys.readouterr().err
    monkeypatch.setattr("sys.stdin", Terminal("y\n"))
    assert main(["daq", "calibrate", "--pairs", str(pairs), "--write", str(config)]) == 0
    text = config.read_text()
    assert "  tank1: {gain: 5.43096, offset: 0.238976}\n  tank2: {gain: 5.55574, offset: 1.54193}\n" in text
    assert text.replace("tank1: {gain: 5.43096, offset: 0.238976}", "tank1: {gain: 2.0, offset: 0.0}").replace(
        "tank2: {gain: 5.55574, offset: 1.54193}", "tank2: {gain: 2.0, offset: 0.0}") == original
    sensors = load_daq_config(config).sensors
    assert (sensors[0].gain, sensors[1].offset, sensors[2].gain) == (5.43096, 1.54193, 2.0)


def _cascade_par(tmp_path: Path) -> tuple[Path, str]:
    """The shipped cascade file with outlets of a rig not yet calibrated."""
    text = (ROOT / "params" / "coupled-cascade.par").read_text()
    text = text.replace("alpha1 0.0097909\n", "alpha1 0.0095\n").replace("alpha2 0.0098811\n", "alpha2 0.0101\n")
    path = tmp_path / "ctp.par"
    path.write_text(text)
    return path, text


def test_write_puts_his_alphas_into_the_par_and_the_fit_into_the_daq_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """Table 1 on the cascade: the .par gets Desautel's alpha1 0.0097909, alpha2
    0.0098811 (2.3.1), every other line as it was; the diff is printed first."""
    pairs = tmp_path / "table1.txt"
    pairs.write_text(TABLE_1)
    par, par_text = _cascade_par(tmp_path)
    config = tmp_path / "rig.yaml"
    daq_text = (ROOT / "params" / "virtual-rig.yaml").read_text()
    config.write_text(daq_text)
    monkeypatch.setattr("sys.stdin", io.StringIO(""))
    assert main(["daq", "calibrate", "--pairs", str(pairs), "--par", str(par), "--write", str(config),
                 "--yes"]) == 0
    out = capsys.readouterr().out
    assert "  alpha1 0.0097909   (.par: 0.0095000)\n  alpha2 0.0098811   (.par: 0.0101000)\n" in out
    assert f"--- {par}\n+++ {par} (calibrated)\n" in out
    assert "-alpha1 0.0095\n-alpha2 0.0101\n+alpha1 0.0097909\n+alpha2 0.0098811\n" in out
    assert par.read_text() == par_text.replace("alpha1 0.0095\n", "alpha1 0.0097909\n").replace(
        "alpha2 0.0101\n", "alpha2 0.0098811\n")
    assert config.read_text() == daq_text.replace(
        "tank1: {gain: 2.0, offset: 0.0}", "tank1: {gain: 5.43096, offset: 0.238976}").replace(
        "tank2: {gain: 2.0, offset: 0.0}", "tank2: {gain: 5.55574, offset: 1.54193}")


def test_write_without_a_terminal_needs_yes_and_changes_nothing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    pairs = tmp_path / "table1.txt"
    pairs.write_text(TABLE_1)
    par, par_text = _cascade_par(tmp_path)
    monkeypatch.setattr("sys.stdin", io.StringIO("y\n"))  # a pipe: not asked, even saying y
    assert main(["daq", "calibrate", "--pairs", str(pairs), "--par", str(par), "--write"]) == 1
    err = capsys.readouterr().err
    assert "not written: no terminal to ask" in err and "--yes" in err, err
    assert par.read_text() == par_text


def test_write_puts_the_quadruple_tanks_outlets_into_its_time_constants(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Pairs settled on the preset's plant written into a file whose TimeConst1 is off:
    it comes back as the preset's 62.703390 s (a1 at the file's diameter and level)."""
    p = PRESET.quadtank_constants()
    rows = ["u1 u2 volts1 volts2 volts3 volts4 level1 level2 level3 level4"]
    for v in (2.0, 2.5, 3.0):
        h = steady_state_levels((v, v), p)  # written to 12 digits: the fit is exact
        rows.append(" ".join(f"{x:.12g}" for x in (v, v, *(p.kc * x for x in h), *h)))
    table = tmp_path / "pairs.txt"
    table.write_text("\n".join(rows) + "\n")
    par = write_par(tmp_path / "off.par", PRESET.with_values({"SIMULATION.TimeConst1": 70.0}))
    before = par.read_text()
    assert "TimeConst1 70.000000\n" in before
    assert main(["daq", "calibrate", "--pairs", str(table), "--par", str(par), "--write", "--yes"]) == 0
    assert par.read_text() == before.replace("TimeConst1 70.000000\n", "TimeConst1 62.703390\n")
    out = capsys.readouterr().out
    assert "-TimeConst1 70.000000\n+TimeConst1 62.703390\n" in out, out


def test_writing_what_the_files_hold_writes_nothing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    pairs = tmp_path / "table1.txt"
    pairs.write_text(TABLE_1)
    par = tmp_path / "ctp.par"
    par.write_text((ROOT / "params" / "coupled-cascade.par").read_text())
    monkeypatch.setattr("sys.stdin", io.StringIO(""))
    assert main(["daq", "calibrate", "--pairs", str(pairs), "--par", str(par), "--write"]) == 0
    assert "nothing to write" in capsys.readouterr().err


def test_a_daq_file_without_a_calibration_section_gets_one() -> None:
    from quadtank_tui.core.calibration.fits import SensorCalibration
    from quadtank_tui.daq.calibrate import with_calibration
    from quadtank_tui.daq.config import parse_daq_config

    text = with_calibration("preset: labjack\nhost: 10.0.0.2  # the lab's\n",
                            {1: SensorCalibration(2.1, -0.3), 3: SensorCalibration(1.9, 0.25)})
    assert text == ("preset: labjack\nhost: 10.0.0.2  # the lab's\n\ncalibration:\n"
                    "  tank1: {gain: 2.1, offset: -0.3}\n  tank3: {gain: 1.9, offset: 0.25}\n")
    c = parse_daq_config(text)
    assert (c.sensors[0].gain, c.sensors[0].offset, c.sensors[2].offset) == (2.1, -0.3, 0.25)


class _Recorder:
    """A rig's sensors that settle at once, recording every request with its time."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, object, float]] = []

    def _note(self, what: str, value: object = None) -> None:
        self.calls.append((what, value, time.monotonic()))

    def arm(self, tsamp: float) -> None:
        self._note("arm", tsamp)

    def read_raw_volts(self) -> tuple[float, ...]:
        self._note("read")
        return (1.0, 1.0, 1.0, 1.0)

    def write_pumps(self, u: tuple[float, float]) -> None:
        self._note("write", u)

    def safe_state(self) -> None:
        self._note("safe")


def test_the_procedure_is_armed_and_holds_the_pumps_while_the_operator_reads_the_scales() -> None:
    """Armed before the first pump write (so a kill stops the pumps: the next
    test), and while the operator takes 0.4 s to answer the pumps are still
    written every poll: the levels stay settled and a watchdog armed for the poll
    keeps hearing from us (before, nothing was written until the answer came)."""
    sensors = _Recorder()
    asked: list[float] = []

    def slow_operator(volts: tuple[float, float], settled: tuple[float, ...]) -> list[float]:
        asked.append(time.monotonic())
        time.sleep(0.4)
        return [1.0, 2.0, 3.0, 4.0]

    pairs = run_procedure(sensors, [3.0], SettleRule(window=2, tol=0.01, timeout=5.0), slow_operator,
                          poll=0.05, sleep=lambda s: None)
    assert pairs.columns["level4"] == [4.0]
    kinds = [c[0] for c in sensors.calls]
    assert kinds[0] == "arm" and sensors.calls[0][1] == 0.05 and kinds[-1] == "safe"
    during = [c for c in sensors.calls if c[0] == "write" and c[2] > asked[0]]
    assert len(during) >= 5 and all(c[1] == (0.3, 0.3) for c in during), during
    gaps = np.diff([asked[0]] + [c[2] for c in during])
    assert gaps.max() < 0.05 + 0.1, gaps  # one poll, and some slack for a loaded machine


@pytest.mark.wallclock
def test_killed_while_asking_for_the_heights_the_guard_stops_the_pumps(
        rig: Callable[..., Any], tmp_path: Path, poll: Callable[..., bool]) -> None:
    """`daq calibrate` killed while it waits for the operator (the pumps at the
    first voltage) on a device without a watchdog: the guard, started by the
    arming, sets the pumps to 0 (before, they ran on at 2 V until someone came)."""
    bare = tmp_path / "bare.yaml"
    bare.write_text(VIRTUAL_RIG.read_text() + "watchdog: none\n")
    r = rig("--map", str(bare), "--speed", "4000")
    config = tmp_path / "rig.yaml"
    config.write_text(rig_yaml(r.port, bare))
    proc = subprocess.Popen(
        [sys.executable, "-m", "quadtank_tui", "daq", "calibrate", str(config), "--volts", "2",
         "--poll", "0.05", "--window", "5", "--tol", "0.05"],
        cwd=Path(__file__).parents[2], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True)
    try:
        assert poll(lambda: min(r.dacs()) > 1.9 or proc.poll() is not None, 60.0), r.dacs()
        assert proc.stderr is not None
        assert "waiting for the levels to settle" in proc.stderr.readline()
        line = proc.stderr.readline()  # the settled sensors, then the question (no newline)
        assert line.startswith("settled: sensors"), line
        time.sleep(0.5)  # the operator walks to the scales; the pumps run on
        assert min(r.dacs()) > 1.9 and proc.poll() is None
        proc.kill()
        t0 = time.monotonic()
        assert poll(lambda: r.dacs() == (0.0, 0.0), 30.0), r.dacs()
        assert time.monotonic() - t0 < 1.0 + 0.1 + 0.5  # the guard's gap at a 0.05 s poll (1 s), one exchange
    finally:
        proc.kill()
        proc.communicate(timeout=30)
