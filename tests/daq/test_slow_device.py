"""A slow or hung Modbus device: a fault within a bounded time, a run that ends on
time, and a log that never silently carries a wrong time base.

- A device that accepts the connection and never answers (tests/daq/conftest.py
  SilentDevice): each request is waited for once (`timeout`), never twice, so the
  sample faults within one timeout and safe_state gives up within one more per
  pump.  A headless `--duration 5` ended after more than 200 s before; it ends on
  time now, because a real process's time passes whether or not the loop keeps up
  (the sampling slots the clock skipped count).
- A device slower than the sampling time but within its timeout: the samples come
  0.3 s apart for a TSamp of 0.1 s.  The rows are still logged (the run does not
  fault: the data are real), but each late row follows a `% late:` line that says
  how far apart it really was, the `t` of the trends moves on over the missed
  slots, and the summary says so.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.cli import main
from quadtank_tui.daq.modbus import ModbusBackend
from quadtank_tui.engine.commands import SetOperation, SetState
from quadtank_tui.engine.runner import build_engine
from quadtank_tui.files.log_reader import read_log

ROOT = Path(__file__).parents[2]
PAR = str(ROOT / "params" / "default.par")  # TSamp 0.1 s


def config_file(tmp_path: Path, port: int, timeout: float) -> Path:
    text = (ROOT / "params" / "virtual-rig.yaml").read_text()
    text = text.replace("port: 5020", f"port: {port}").replace("timeout: 0.2", f"timeout: {timeout}")
    path = tmp_path / "rig.yaml"
    path.write_text(text)
    return path


def test_a_hung_device_faults_within_one_timeout_and_the_pumps_are_tried_within_one_more_each(
        silent_device, tmp_path: Path) -> None:
    backend = ModbusBackend(_config(silent_device.port, 0.2))
    engine = build_engine(None, daq=backend, clock="manual", params_dir=ROOT / "params", logs_dir=tmp_path)
    try:
        assert engine.submit(SetOperation("Active")).result().ok
        assert engine.submit(SetState("Run")).result().ok
        t0 = time.monotonic()
        snap = engine.step()
        took = time.monotonic() - t0
        assert snap.state == "Pause"
        assert snap.fault == (f"modbus 127.0.0.1:{silent_device.port}: read of AIN0..AIN3 (input registers 0-7) "
                              f"at 127.0.0.1:{silent_device.port} failed: no answer within 0.2 s; pumps NOT "
                              "confirmed at 0 (left to the guard process and the device's watchdog to stop them): "
                              f"{backend.safe_state_error}")
        assert backend.safe_state_error.count("no answer within 0.2 s") == 2  # each pump tried, once
        # read 0.2 s + two pump writes 0.2 s each = 0.6 s (it was 0.4 + 0.8 = 1.2 s)
        assert 0.55 < took < 6.0  # room for a loaded machine; the count above is the exact check
    finally:
        engine.stop()


def test_a_headless_run_against_a_hung_device_ends_on_time(silent_device, tmp_path: Path) -> None:
    """`quadtank run --daq ... --duration 2` against a device that never answers: the
    run lasts 2 s (plus the start of a Python and one last tick), says FAULT, exit 1.
    (A run of 5 s took more than 200 s: every sample waited its timeouts; 2 s would
    take 80 s so.)"""
    config = config_file(tmp_path, silent_device.port, 0.2)
    t0 = time.monotonic()
    run = subprocess.run(
        [sys.executable, "-m", "quadtank_tui", "run", "--daq", str(config), "--realtime", "--duration", "2",
         "--log", str(tmp_path / "hung.log"), "--par", PAR],
        capture_output=True, text=True, timeout=60)
    took = time.monotonic() - t0
    assert run.returncode == 1, run.stderr
    assert f"FAULT      modbus 127.0.0.1:{silent_device.port}: read of AIN0..AIN3" in run.stdout
    assert "failed: no answer within 0.2 s" in run.stdout and "Traceback" not in run.stderr
    assert 2.0 < took < 30.0, took       # a loaded machine starts Python in seconds


def test_late_samples_are_noted_in_the_log(rig: Callable, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    r = rig("--reply-delay", "0.15")
    out = tmp_path / "slow.log"
    t0 = time.monotonic()
    status = main(["run", "--daq", str(config_file(tmp_path, r.port, 1.0)), "--realtime", "--duration", "3",
                   "--log", str(out), "--par", PAR, ])
    took = time.monotonic() - t0
    text = capsys.readouterr().out
    assert status == 0, text
    assert 2.9 < took < 15.0, took       # 3 s of process time, not 3 s of samples (a 15 s run took 182 s)
    lines = out.read_text().splitlines()
    rows = [ln for ln in lines if ln and not ln.startswith("%")]
    notes = [ln for ln in lines if ln.startswith("% late:")]
    assert 3 <= len(rows) <= 12                              # a read and a write of 0.15 s each per sample
    # Every row after the first came at least two slots late, and says so just before it.
    body = lines[lines.index("") + 1:]
    assert body[0] == rows[0]
    for note, row in zip(body[1::2], body[2::2]):
        assert note.startswith("% late: the next row was sampled ") and row in rows
        gap = float(note.split("sampled ")[1].split(" s")[0])
        assert gap >= 0.3 - 1e-9 and note.endswith("s after the previous one, not TSamp 0.1 s")
    assert len(notes) == len(rows) - 1
    assert read_log(out).rows == len(rows)                   # readers skip the notes
    assert f"late       {len(notes)} of the {len(rows)} rows came late" in text


def _config(port: int, timeout: float):
    import dataclasses

    from quadtank_tui.daq.config import load_daq_config

    return dataclasses.replace(load_daq_config(ROOT / "params" / "virtual-rig.yaml"),
                               host="127.0.0.1", port=port, timeout=timeout)
