"""No test leaves a guard behind (tests/conftest.py `guards_of_this_test`, autouse in
tests/daq and tests/session): a guard whose program died retries its stop on a dead
or hung device every 0.25 s for up to 2 minutes (daq/guard.py GIVE_UP_S), right on
a rig, a process outliving its test here: a run of tests/daq left 2 of its 44
guards, for 120 s each (test_active_faults' fault on a live link, test_session_rig's
killed session); with the fixture, 0 of 39 in tests/daq and tests/session, the
longest-lived 5.5 s, within its test.  The guards a test ends are its own, found
by the mark its processes inherit, never another test's."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from typing import Any

import pytest

from quadtank_tui.daq.guard import Guard, GuardSpec
from quadtank_tui.files.proc import process_state

pytestmark = [pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc"),
              pytest.mark.wallclock]


def _orphaned_guard(port: int) -> Guard:
    """A guard whose program died without its bye: it tries the stop on the device
    at `port`, again and again."""
    program = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    guard = Guard(GuardSpec(program.pid, "127.0.0.1", port, 1, 0.2, [("DAC0", 1000, [0, 0])], 1.0))
    program.kill()
    program.wait()
    return guard


def test_a_guard_retrying_on_a_hung_device_ends_with_its_test_and_no_other(
        silent_device: Any, guards_of_this_test: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    mine = _orphaned_guard(silent_device.port)
    other_test = type(guards_of_this_test)()  # as if another test, in another worker, ran one meanwhile
    monkeypatch.setenv(guards_of_this_test.variable, other_test.mark)
    theirs = _orphaned_guard(silent_device.port)
    monkeypatch.setenv(guards_of_this_test.variable, guards_of_this_test.mark)
    time.sleep(1.0)  # both gone past their first try (0.2 s timeout): retrying every 0.25 s
    assert guards_of_this_test.alive() == [mine.pid] and other_test.alive() == [theirs.pid]
    assert guards_of_this_test.end() == []
    assert process_state(mine.pid) == ""
    assert process_state(theirs.pid) not in ("", "T"), "another test's guard was ended"
    assert other_test.end() == [] and process_state(theirs.pid) == ""
    assert os.environ[guards_of_this_test.variable] == guards_of_this_test.mark
