"""A real-time clock's driving thread runs SCHED_FIFO while it drives (engine/driver.py):
a sleeping ordinary thread woke 0.7-9 ms late at p99 under load, waiting for a core."""

from __future__ import annotations

import os
import sys
import threading
from typing import Callable

import pytest

from quadtank_tui.engine.driver import RT_PRIORITY, SWITCH_INTERVAL, Driver
from quadtank_tui.engine.runner import Engine

pytestmark = pytest.mark.skipif(not hasattr(os, "sched_setscheduler"), reason="no POSIX scheduling policies")


def _fifo_allowed() -> bool:
    allowed: list[bool] = []

    def probe() -> None:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO | os.SCHED_RESET_ON_FORK, os.sched_param(RT_PRIORITY))
            allowed.append(True)
        except OSError:
            allowed.append(False)

    thread = threading.Thread(target=probe)
    thread.start()
    thread.join()
    return allowed[0]


def _policies(engine: Engine) -> tuple[list[int], int, int]:
    """The driving thread's policy at each of 3 samples, that of a thread it starts
    meanwhile, and its own after the drive (a thread of its own: the test's stays as it is)."""
    during: list[int] = []
    child: list[int] = []
    after: list[int] = []

    def before(_: object) -> None:
        during.append(os.sched_getscheduler(0))
        if len(during) == 2:
            started = threading.Thread(target=lambda: child.append(os.sched_getscheduler(0)))
            started.start()
            started.join()

    def drive() -> None:
        Driver(engine, samples=3, before=before).run()
        after.append(os.sched_getscheduler(0))

    thread = threading.Thread(target=drive)
    thread.start()
    thread.join(10)
    return during, child[0], after[0]


def test_a_real_time_drive_runs_fifo_and_gives_the_policy_back(make_engine: Callable[..., Engine]) -> None:
    if not _fifo_allowed():
        pytest.skip("SCHED_FIFO is not allowed here (not root, no CAP_SYS_NICE, no RLIMIT_RTPRIO)")
    engine = make_engine(clock="realtime")
    engine.clock.set_period(0.01)
    during, child, after = _policies(engine)
    fifo = os.SCHED_FIFO | os.SCHED_RESET_ON_FORK
    assert during == [fifo] * 3
    assert child == os.SCHED_OTHER   # a thread it starts (a LoadPar's read, an MPC's design) is ordinary
    assert after == os.SCHED_OTHER


def test_a_virtual_clock_keeps_the_ordinary_policy(make_engine: Callable[..., Engine]) -> None:
    engine = make_engine(clock="virtual", speed=100.0)
    during, _, after = _policies(engine)
    assert during == [os.SCHED_OTHER] * 3 and after == os.SCHED_OTHER


def test_a_real_time_drive_hands_the_gil_over_sooner_and_puts_the_interval_back(
        make_engine: Callable[..., Engine]) -> None:
    """A woken driving thread waited for the GIL up to Python's 5 ms switch interval
    (the file thread, a client's reader): session_timing's p99 at 50 ms was 0.58 ms."""
    default = sys.getswitchinterval()
    assert default > SWITCH_INTERVAL
    seen: list[float] = []
    engine = make_engine(clock="realtime")
    engine.clock.set_period(0.01)
    Driver(engine, samples=3, before=lambda _: seen.append(sys.getswitchinterval())).run()
    assert seen == [SWITCH_INTERVAL] * 3
    assert sys.getswitchinterval() == default
    virtual = make_engine(clock="virtual", speed=100.0)
    Driver(virtual, samples=3, before=lambda _: seen.append(sys.getswitchinterval())).run()
    assert seen[3:] == [default] * 3   # a virtual clock leaves it alone
