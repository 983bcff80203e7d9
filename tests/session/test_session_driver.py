"""The driver served on a session's event loop (engine/driver.py, session/host.py):
a client's command ends the wait for a far sample and is applied between samples;
the session samples while another thread of the process is busy.  (These were the
tests of Engine.start, the engine's own thread, before the session became the one
way to run the loop with clients.)"""

from __future__ import annotations

import asyncio
import time
from typing import Callable

from sessionkit import ThreadSession

from quadtank_tui.engine import commands as c
from quadtank_tui.session.client import SessionClient


def test_a_command_ends_the_drivers_wait_and_is_applied_between_samples(
        thread_session, poll: Callable[..., bool]) -> None:
    """A sample 10 s away (10 s sampling at x1) is waited for on the event loop: a
    client's command, and the stop, are taken at once, not after the wait."""
    s: ThreadSession = thread_session(speed=1.0, tsamp_ms=10000)
    assert poll(lambda: s.engine.snapshot().stats.samples == 1, 30.0, 0.001)  # the first is due at once
    with SessionClient(s.path) as client:
        t0 = time.monotonic()
        assert client.submit(c.SetParams({"REFERENCE ONE.Mean": 0.5})).result(10).ok
        assert s.engine.snapshot().params.get("REFERENCE ONE.Mean") == 0.5
        assert s.engine.snapshot().stats.samples == 1
    s.stop()
    assert not s.thread.is_alive() and time.monotonic() - t0 < 5.0  # not the 10 s to the next sample


def test_the_session_samples_while_another_thread_is_busy(thread_session) -> None:
    """A UI-like event loop whose handler hogs its thread (a slow frame, in pure
    Python) in the session's process: the driver samples during the frame."""
    s: ThreadSession = thread_session(speed=1000.0)
    with SessionClient(s.path) as client:
        assert client.submit(c.SetState("Run")).result(10).ok
    progress: list[int] = []

    async def slow_frame() -> None:
        x = 0
        for i in range(1_500_000):
            x += i * i
            if i % 250_000 == 0:
                progress.append(s.engine.snapshot().stats.samples)

    asyncio.run(slow_frame())
    assert progress == sorted(progress) and progress[-1] > progress[0]


def test_a_simulated_sessions_disk_work_is_off_the_drivers_thread(thread_session) -> None:
    """A session on a virtual clock (the TUI's Simul) writes its log and saves on
    the file thread, as a rig's does: a slow fsync costs it no deadline
    (tests/engine/test_file_thread.py measures that on the driver)."""
    s: ThreadSession = thread_session()
    assert not s.engine.clock.realtime and s.engine.loop.files.threaded
