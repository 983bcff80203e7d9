"""The rig is safe when the program is not: `quadtank run --daq` killed or stopped.

A virtual rig on loopback and a headless run in a process of its own; what counts
is what the rig's pump registers (DAC0/DAC1) say, read by a client of the test's.
SIGKILL: the guard process writes them to 0 (on a map with `watchdog: none`, so
nothing else could).  SIGSTOP: the device's watchdog, armed by the run for 1 s at
TSamp 0.1, does; after SIGCONT the run pauses and says why, in its summary and in
its log, instead of driving the pumps again.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable

import pytest

from daqkit import VIRTUAL_RIG, rig_yaml

pytestmark = [pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc and pidfd"),
              pytest.mark.wallclock]

ROOT = Path(__file__).parents[2]
#: The watchdog timeout the run arms at TSamp 0.1 s (max(2 Ts, 1 s)) plus one sample.
WITHIN = 1.0 + 0.1


def _run(tmp_path: Path, config: Path, duration: float) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "quadtank_tui", "run", "--daq", str(config), "--duration", f"{duration:g}",
         "--log", str(tmp_path / "run.log")],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _pumps_on(r: Any, proc: subprocess.Popen[str], poll: Callable[..., bool]) -> None:
    assert poll(lambda: min(r.dacs()) > 2.9 or proc.poll() is not None, 60.0)
    assert proc.poll() is None, proc.communicate()


def test_sigkill_of_the_run_the_guard_puts_the_pumps_at_0(
        rig: Callable[..., Any], tmp_path: Path, poll: Callable[..., bool]) -> None:
    bare = tmp_path / "bare.yaml"  # a device without a watchdog: only the guard can stop its pumps
    bare.write_text(VIRTUAL_RIG.read_text() + "watchdog: none\n")
    r = rig("--map", str(bare))
    config = tmp_path / "rig.yaml"
    config.write_text(rig_yaml(r.port, bare))
    proc = _run(tmp_path, config, 60)
    _pumps_on(r, proc, poll)
    proc.kill()
    t0 = time.monotonic()
    assert poll(lambda: r.dacs() == (0.0, 0.0), 30.0), r.dacs()
    took = time.monotonic() - t0
    _, err = proc.communicate(timeout=30)  # the guard shares its stderr: it has said why and ended
    assert f"quadtank guard: the program driving the rig (pid {proc.pid}) ended without stopping its pumps " \
           f"(killed, or it crashed); pumps (DAC0, DAC1) set to 0 over the guard's own connection to " \
           f"127.0.0.1:{r.port}" in err
    assert "watchdog: none declared by" in err  # said at the start
    assert took < WITHIN, f"the pumps ran {took:.2f} s after the kill"


def test_sigstop_the_devices_watchdog_stops_the_pumps_and_sigcont_pauses(
        rig: Callable[..., Any], tmp_path: Path, poll: Callable[..., bool]) -> None:
    r = rig()
    config = tmp_path / "rig.yaml"
    config.write_text(rig_yaml(r.port))
    proc = _run(tmp_path, config, 6)
    _pumps_on(r, proc, poll)
    proc.send_signal(signal.SIGSTOP)
    time.sleep(WITHIN + 0.2)  # no request meanwhile: a read clears a LabJack's timer
    assert r.dacs() == (0.0, 0.0)
    proc.send_signal(signal.SIGCONT)
    out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 1, out
    fault = next(line for line in out.splitlines() if line.startswith("FAULT"))
    assert "no request reached the rig for " in fault and "longer than the watchdog timeout 1 s" in fault
    assert "Active control ends here" in fault
    notes = [line for line in (tmp_path / "run.log").read_text().splitlines() if "paused, pumps at 0" in line]
    assert len(notes) == 1 and notes[0].startswith("% t = ") and "no request reached the rig" in notes[0]
    time.sleep(0.3)
    assert r.dacs() == (0.0, 0.0)  # never a silent return to the 3 V of before


def test_a_bye_written_before_the_guard_has_started_ends_it(poll: Callable[..., bool]) -> None:
    """A program that drives for less than the guard's start (a run of a few samples,
    a fault at the first) writes its bye before the guard has read its spec: the
    guard ends on it, not when the program ends (it read the spec with a buffered
    readline, which kept the bye out of its watch: 7 guards outlived their tests in
    a run of tests/daq, each waiting for pytest to end to zero the pumps of a rig
    long gone)."""
    from quadtank_tui.daq.guard import Guard, GuardSpec
    from quadtank_tui.files.proc import process_state

    # a live program (this one) and a port nobody answers on: the guard must not act
    guard = Guard(GuardSpec(os.getpid(), "127.0.0.1", 9, 1, 0.2, [("DAC0", 1000, [0, 0])], 1.0))
    guard.release(wait=0.0)  # microseconds after the spec: the guard's interpreter is still starting
    assert poll(lambda: process_state(guard.pid) == "", 10.0), "the guard outlived the program's bye"
