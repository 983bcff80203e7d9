"""files/proc.py: whether a process runs, is the one a record names, and whose it is.

Its pids come from files other users may write (session records, the DAQ lock):
0 and negative pids are no process (a signal 0 to them would probe a process group
and say "alive"), a zombie is gone, and a recycled pid is not the recorded process.
"""

from __future__ import annotations

import os
import subprocess
import sys

from quadtank_tui.files.proc import pid_alive, process_owner, process_start, process_state


def test_no_pid_is_no_process() -> None:
    for pid in (0, -1, -os.getpgrp()):
        assert process_state(pid) == ""
        assert not pid_alive(pid)


def test_this_process_runs_and_is_the_one_recorded() -> None:
    me = os.getpid()
    start = process_start(me)
    assert process_state(me) == "R" and start is not None
    assert pid_alive(me) and pid_alive(me, start)
    assert not pid_alive(me, start + 1)  # the same pid started at another time: recycled
    assert process_owner(me) == os.getuid()


def test_a_zombie_is_gone() -> None:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    try:
        os.waitid(os.P_PID, child.pid, os.WEXITED | os.WNOWAIT)  # exited, not reaped
        assert process_state(child.pid) == "" and not pid_alive(child.pid)
    finally:
        child.wait()
    assert process_start(child.pid) is None and process_owner(child.pid) is None
