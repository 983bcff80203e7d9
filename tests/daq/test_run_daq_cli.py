"""`quadtank run --daq CONFIG`: a headless experiment in Active on a virtual rig."""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.cli import build_parser, main
from quadtank_tui.commands.tui import build_tui
from quadtank_tui.engine.commands import SetOperation, SetParams, SetState
from quadtank_tui.files.log_reader import read_log
from daqkit import missed_before_the_last_row, rig_yaml

pytestmark = pytest.mark.wallclock  # a rig subprocess, real time

ROOT = Path(__file__).parents[2]


def config_for(tmp_path: Path, port: int) -> Path:
    """params/virtual-rig.yaml pointed at `port`."""
    text = rig_yaml(port)
    path = tmp_path / "rig.yaml"
    path.write_text(text)
    return path


def test_run_daq_logs_an_active_experiment(rig: Callable, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    r = rig("--speed", "20")
    out = tmp_path / "active.log"
    status = main(["run", "--daq", str(config_for(tmp_path, r.port)), "--speed", "20",
                   "--duration", "30", "--log", str(out), "--par", str(ROOT / "params" / "default.par")])
    text = capsys.readouterr().out
    assert status == 0, text
    assert "FAULT" not in text
    # 300 sampling slots of 0.1 s: each either sampled (a row) or, at x20 (5 ms) on a
    # busy machine, missed - the rig's time does not wait, the log notes the late rows
    # (a late last row may carry the count past 300 by the slots it missed).
    m = re.match(r"ran 30 s: (\d+) samples, (\d+) overruns(?: \((\d+) sampling slots skipped\))?", text)
    assert m is not None, text
    samples, overruns, skipped = (int(w or 0) for w in m.groups())
    log = read_log(out)
    assert overruns <= samples and (overruns == 0) == (skipped == 0)
    assert 300 <= samples + skipped <= 300 + missed_before_the_last_row(out, 0.1) and log.rows == samples
    notes = out.read_text().count("% late:")
    assert (notes > 0) == (f"late       {notes} of the {samples} rows came late" in text)
    assert abs(log.columns()["u1"][-1] - 0.3) < 1e-9
    assert r.dacs() == (0.0, 0.0)  # the run ended: pumps commanded to 0


def test_run_daq_without_a_rig_says_why(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import socket

    with socket.socket() as s:  # a port nobody listens on: bound (so no other test takes it), never listening
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
        status = main(["--daq", str(config_for(tmp_path, port)), "run", "--speed", "20", "--duration", "1",
                       "--log", str(tmp_path / "x.log"), "--par", str(ROOT / "params" / "default.par")])
    text = capsys.readouterr().out
    assert status == 1
    assert f"FAULT      modbus 127.0.0.1:{port}: read of AIN0..AIN3" in text
    assert "cannot connect" in text


def test_run_daq_with_a_bad_config_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("host: 127.0.0.1\ntimeout: soon\n")
    assert main(["run", "--daq", str(bad), "--duration", "1", "--log", str(tmp_path / "x.log")]) == 2
    assert capsys.readouterr().err.strip() == f"quadtank: error: {bad}:2: timeout: must be a number, got 'soon'"


@pytest.mark.parametrize("sig, status, said", [("SIGINT", 130, "interrupted"), ("SIGTERM", 143, "stopped by SIGTERM"),
                                               ("SIGHUP", 129, "stopped by SIGHUP"),
                                               ("SIGQUIT", 131, "stopped by SIGQUIT"),
                                               ("SIGTSTP", 148, "stopped by SIGTSTP: a run on a rig is not suspended")])
def test_ctrl_c_or_sigterm_commands_the_pumps_to_zero_and_keeps_the_log(
        rig: Callable, poll: Callable, tmp_path: Path, sig: str, status: int, said: str) -> None:
    """SIGINT (Ctrl-C), SIGTERM (kill, systemd), SIGHUP (the SSH session dropped),
    SIGQUIT (Ctrl-\\) or SIGTSTP (Ctrl-Z: suspended, the pumps would run on) to a
    running `quadtank run --daq`: the program (not the rig's watchdog, which is off
    here) puts the pumps at 0, exits 128 + the signal without a traceback, and the
    rows logged so far are in the partial log."""
    import signal
    import subprocess
    import sys

    r = rig("--speed", "20", "--watchdog", "0")
    out = tmp_path / "interrupted.log"
    run = subprocess.Popen(
        [sys.executable, "-m", "quadtank_tui", "run", "--daq", str(config_for(tmp_path, r.port)),
         "--speed", "20", "--duration", "3000", "--log", str(out), "--par", str(ROOT / "params" / "default.par")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        # A job a non-interactive shell starts in the background inherits SIGINT
        # ignored (POSIX), and so would the program: give it the terminal's default.
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    partial = tmp_path / "interrupted.log.partial"  # LOGGING.LogFile follows --log

    def logged(rows: int) -> bool:
        try:
            return read_log(partial).rows >= rows
        except (OSError, ValueError):  # not there yet, or its header half-written
            return False

    try:
        assert poll(lambda: logged(3) and r.dacs() != (0.0, 0.0), timeout=30.0)
        rows_before = read_log(partial).rows
        run.send_signal(getattr(signal, sig))
        _, err = run.communicate(timeout=30)
    finally:
        if run.poll() is None:
            run.kill()
    assert run.returncode == status
    assert "Traceback" not in err and f"quadtank: {said}" in err
    assert r.dacs() == (0.0, 0.0)
    assert read_log(partial).rows >= rows_before


def test_top_level_daq_without_a_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`quadtank --daq CONFIG`: the file is checked before anything runs; a good one
    gives the TUI an engine that offers Active mode on a real-time clock."""
    engine, _app = build_tui(build_parser().parse_args(["--daq", str(ROOT / "params" / "virtual-rig.yaml")]))
    try:
        assert engine.snapshot().active_available and engine.snapshot().realtime
    finally:
        engine.stop()
    bad = tmp_path / "bad.yaml"
    bad.write_text("port: 0\n")
    assert main(["--daq", str(bad)]) == 2
    assert capsys.readouterr().err.strip() == f"quadtank: error: {bad}:1: port: must be in 1..65535, got 0"


def test_the_tuis_loop_process_drives_the_rig_and_leaves_its_pumps_at_0(rig: Callable, tmp_path: Path) -> None:
    """The TUI's engine runs in its own process, which opens the DAQ link itself:
    Active, Run, manual inputs reach the rig's registers; stopping puts them at 0."""
    r = rig("--speed", "1")
    engine, _app = build_tui(build_parser().parse_args(["--daq", str(config_for(tmp_path, r.port))]))
    try:
        for command in (SetOperation("Active"), SetParams({"REFERENCE ONE.Mean": 0.4, "REFERENCE TWO.Mean": 0.5}),
                        SetState("Run")):
            result = engine.submit(command).result(timeout=10)
            assert result.ok, result.message
        engine.start()
        deadline = time.monotonic() + 60
        while engine.snapshot().k < 10 and time.monotonic() < deadline:
            time.sleep(0.05)
        s = engine.snapshot()
        assert s.k >= 10 and s.fault is None
        assert (s.operation, s.backend) == ("Active", f"modbus 127.0.0.1:{r.port}")
        assert s.u == pytest.approx((0.4, 0.5)) and r.dacs() == pytest.approx((4.0, 5.0), abs=1e-4)
    finally:
        engine.stop()
    assert r.dacs() == (0.0, 0.0)


def test_when_the_loop_process_is_killed_the_tui_commands_the_pumps_to_0(rig: Callable, tmp_path: Path) -> None:
    """kill -9 of the loop's process (a private session's; the OOM killer, say): it
    cannot stop in order, so the TUI's process opens a link of its own and commands the pumps to 0 (the rig's
    watchdog is off here), and the screen's fault line says so."""
    import os
    import signal

    r = rig("--speed", "1", "--watchdog", "0")
    engine, _app = build_tui(build_parser().parse_args(["--daq", str(config_for(tmp_path, r.port))]))
    try:
        for command in (SetOperation("Active"), SetParams({"REFERENCE ONE.Mean": 0.4}), SetState("Run")):
            assert engine.submit(command).result(timeout=10).ok
        engine.start()
        deadline = time.monotonic() + 60
        while r.dacs()[0] == 0.0 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert r.dacs()[0] == pytest.approx(4.0, abs=1e-4)
        os.kill(engine.info.pid, signal.SIGKILL)  # the private session's process
        deadline = time.monotonic() + 60
        while "commanded to 0" not in (engine.snapshot().fault or "") and time.monotonic() < deadline:
            time.sleep(0.05)
        fault = engine.snapshot().fault or ""
        assert (f"the session process {engine.info.id} (pid {engine.info.pid}) stopped unexpectedly; "
                "the pumps were commanded to 0 from this client") in fault
        assert r.dacs() == (0.0, 0.0)
    finally:
        engine.stop()
