"""Hostile files (issue 18, items 12-15): whatever a file option points at, the
answer is one line naming the file (and line, and key where there is one) and
exit status 2, quickly: never a traceback, a hang or gigabytes of memory."""

from __future__ import annotations

import os
import time
import tracemalloc
from pathlib import Path

import pytest

from quadtank_tui.cli import main
from quadtank_tui.daq.config import parse_daq_config
from quadtank_tui.files.par import read_par
from quadtank_tui.files.script import read_script

ROOT = Path(__file__).parents[2]
THESIS_LOG = ROOT / "tests" / "files" / "golden" / "thesis.log"

#: Every command that reads a file, with {} for the file.
READERS = {
    "run --par": ["run", "--par", "{}", "--duration", "1", "--log", "{log}"],
    "run --script": ["run", "--script", "{}", "--duration", "1", "--log", "{log}"],
    "run --daq": ["run", "--daq", "{}", "--duration", "1", "--log", "{log}"],
    "daq check": ["daq", "check", "{}"],
    "rig --map": ["rig", "--map", "{}"],
    "rig --par": ["rig", "--par", "{}"],
    "analyze --par": ["analyze", "--par", "{}"],
    "log info": ["log", "info", "{}"],
    "log export": ["log", "export", "{}", "--to", "csv", "--out", "{log}.csv"],
    "tui --par": ["--par", "{}"],
    "tui --daq": ["--daq", "{}"],
    "design --par": ["design", "--par", "{}", "--no-step"],
    "design --model-file": ["design", "--model-file", "{}", "--no-step"],
    "icad --par": ["icad", "--par", "{}"],
}
YAML_READERS = ("run --script", "run --daq", "daq check", "rig --map")
DAQ_READERS = ("run --daq", "daq check", "rig --map", "tui --daq")


def run_cli(argv: list[str], path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> str:
    """main() on `argv` with the file filled in; its stderr, checked to be one
    error line after exit status 2."""
    args = [a.replace("{}", str(path)).replace("{log}", str(tmp_path / "out.log")) for a in argv]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("quadtank: error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("command", sorted(READERS))
@pytest.mark.parametrize("kind", ["fifo", "directory"])
def test_a_fifo_or_a_directory_is_refused_without_blocking(
        command: str, kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "thing"
    if kind == "fifo":
        os.mkfifo(path)  # open() of a FIFO without a writer blocks forever
    else:
        path.mkdir()
    start = time.monotonic()
    err = run_cli(READERS[command], path, tmp_path, capsys)
    assert time.monotonic() - start < 60  # a blocked open() never returns; 60 s leaves room for a loaded machine
    what = "a FIFO (named pipe)" if kind == "fifo" else "a directory"
    assert f"{path}: cannot read: {what}, not a file" in err


def nested(levels: int) -> str:
    return "host: " + "[" * levels + "]" * levels + "\n"


@pytest.mark.parametrize("command", YAML_READERS)
def test_yaml_nested_500_levels_is_one_line(command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "deep.yaml"
    path.write_text("# deep\n" + nested(500))
    err = run_cli(READERS[command], path, tmp_path, capsys)
    assert f"{path}:2: nested deeper than 32 levels" in err or f"{path} (line 2): nested deeper than 32" in err


@pytest.mark.parametrize("command", DAQ_READERS)
@pytest.mark.parametrize("text, message", [
    ("preset: [labjack]\n", ":1: preset: must be a preset name (labjack, none), got ['labjack']"),
    ("channels: {tank1: [AIN0]}\n", ":1: channels.tank1: ['AIN0'] is not one of the inputs"),
    ("channels: {pump2: {DAC: 1}}\n", ":1: channels.pump2: {'DAC': 1} is not one of the outputs"),
])
def test_wrong_types_in_a_daq_configuration_are_one_line(
        command: str, text: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "daq.yaml"
    path.write_text(text)
    assert f"{path}{message}" in run_cli(READERS[command], path, tmp_path, capsys)


def billion_laughs(levels: int = 9) -> str:
    lines = ['lol: &l0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    lines += [f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * 9) + "]" for i in range(1, levels)]
    return "\n".join(lines) + "\n"


def test_an_alias_bomb_is_refused_quickly_in_bounded_memory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """9^9 = 387 million values once expanded (before: `daq check` ran over 60 s and
    reached 2.8 GB).  Refused from the event stream, before anything is built."""
    path = tmp_path / "bomb.yaml"
    path.write_text(billion_laughs())
    tracemalloc.start()
    start = time.monotonic()
    try:
        err = run_cli(READERS["daq check"], path, tmp_path, capsys)
        elapsed = time.monotonic() - start
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert f"{path}:6: more than 200000 values once its aliases (*name) are expanded" in err
    assert elapsed < 3 and peak < 20e6
    script = tmp_path / "bomb-script.yaml"
    script.write_text("".join(f"- {line.split(': ', 1)[1]}\n" for line in billion_laughs().splitlines()))
    with pytest.raises(ValueError, match="more than 200000 values"):
        read_script(script)


def test_aliases_within_the_bound_still_work() -> None:
    c = parse_daq_config("calibration:\n  tank1: &cal {gain: 2.5, offset: 0.1}\n  tank2: *cal\n", name="a.yaml")
    assert c.sensors[0] == c.sensors[1] and c.sensors[1].gain == 2.5


def test_yaml_exponent_numbers_are_numbers(tmp_path: Path) -> None:
    """YAML 1.1 reads `1e3` as a string ("got '1e3'"); where a number is expected
    it is one."""
    script = tmp_path / "s.yaml"
    script.write_text('- at: 1e3\n  set: {"CONTROLLER ONE.K": 2.5e0, "CONTROLLER ONE.Ti": 3E1}\n')
    event = read_script(script).events[0]
    assert (event.at, dict(event.value)) == (1000.0, {"CONTROLLER ONE.K": 2.5, "CONTROLLER ONE.Ti": 30.0})
    c = parse_daq_config("timeout: 25e-2\ncalibration: {tank1: {gain: 2e0, offset: -5E-1}}\n", name="d.yaml")
    assert (c.timeout, c.sensors[0].offset) == (0.25, -0.5)


def test_a_utf8_byte_order_mark_is_accepted(tmp_path: Path) -> None:
    par = tmp_path / "win.par"
    par.write_bytes(b"\xef\xbb\xbf% TANK PAR-file\r\nSIMULATION\r\nValve1 0.4\r\n")
    assert read_par(par).params.simulation.valves[0] == 0.4
    script = tmp_path / "win.yaml"
    script.write_bytes(b"\xef\xbb\xbf- {at: 0, state: Run}\r\n")
    assert read_script(script).events[0].value == "Run"
    daq = tmp_path / "win-daq.yaml"
    daq.write_bytes(b"\xef\xbb\xbfport: 5020\r\n")
    assert main(["rig", "--map", str(daq), "--port", "70000"]) == 2  # read fine; the port is what is refused


def test_a_denormal_operating_point_is_refused_with_file_line_and_key(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "d.par"
    path.write_text("% TANK PAR-file\nSIMULATION\nOpPoint3 4.9e-324\n")
    err = run_cli(READERS["analyze --par"], path, tmp_path, capsys)
    assert err == f"quadtank: error: {path}, line 3: SIMULATION.OpPoint3: must be >= 0.001, got 4.94066e-324\n"
