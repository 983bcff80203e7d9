"""The guard hears the program: a byte on the pipe after its requests.  A program
frozen (a cgroup freezer, state D) or with a deadlocked loop keeps running as far
as /proc says, but falls silent: after the watchdog timeout the guard stops the
pumps, once (review of issue 24).  Here the frozen program is the test itself: it
holds the pipe open and stops sampling.  A paused loop still reads the levels each
tick and is heard; an orderly end leaves no zombie."""

from __future__ import annotations

import os
import sys
import time
from typing import Any, Callable

import pytest

from quadtank_tui.daq.modbus import ModbusBackend
from test_device_watchdog import _rig_and_backend

pytestmark = [pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc and pidfd"),
              pytest.mark.wallclock]


def test_a_silent_program_has_its_pumps_stopped_once(
        device: Callable[..., Any], capfd: pytest.CaptureFixture[str], poll: Callable[..., bool]) -> None:
    clock, rig, _, _ = _rig_and_backend(device)  # the rig's clock stands still: its watchdog never fires
    backend = ModbusBackend(device((0.0,) * 4, bank=rig).config(), clock=clock)
    backend.arm(0.1)                                  # the guard allows 1 s of silence
    backend.write_pumps((0.3, 0.3))
    guard = backend.guard
    assert guard is not None and rig.pump_volts == (3.0, 3.0)
    t0 = time.monotonic()
    assert poll(lambda: rig.pump_volts == (0.0, 0.0), 5.0), "the guard left a silent program's pumps on"
    assert time.monotonic() - t0 >= 0.9               # not before the timeout
    # the program comes back (it would pause on its own gap; here the clock says none):
    # the guard, hearing it again, does not write again - a paused loop reads only
    backend.write_pumps((0.3, 0.3))
    end = time.monotonic() + 1.6
    while time.monotonic() < end:
        backend.read_levels()
        time.sleep(0.1)
    assert rig.pump_volts == (3.0, 3.0)
    backend.safe_state()
    backend.close()
    err = capfd.readouterr().err
    assert err.count("quadtank guard: ") == 1, err
    assert f"the program driving the rig (pid {os.getpid()}) has not been heard from for " in err
    assert "longer than the watchdog timeout 1 s: running but not sampling (a deadlocked loop?); pumps " \
           "(DAC0, DAC1) set to 0 over the guard's own connection" in err
    # the orderly end: the guard has ended and been reaped (no zombie left)
    assert guard.ended() is None and not os.path.exists(f"/proc/{guard.pid}")
