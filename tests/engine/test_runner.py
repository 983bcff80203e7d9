"""The engine and its driver (engine/driver.py): the driver on the engine's thread and
event loop, commands through futures, clean stops; the driver inline.

Counts, not timing: nothing here depends on how fast the machine is.
"""

from __future__ import annotations

import asyncio
import threading
from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.engine.clock import ManualClock
from quadtank_tui.engine.commands import LogOn, SetParams, SetSpeed, SetState
from quadtank_tui.engine.handle import EngineHandle
from quadtank_tui.engine.runner import Engine

MakeEngine = Callable[..., Engine]
TIMEOUT = 30.0


def wait_samples(engine: Engine, n: int) -> None:
    """Block until the loop has done `n` more samples (an event, not a sleep)."""
    target = engine.snapshot().stats.samples + n
    done = threading.Event()

    def poll() -> None:
        while not done.is_set() and engine.snapshot().stats.samples < target and engine.running:
            done.wait(0.001)
        done.set()

    t = threading.Thread(target=poll)
    t.start()
    t.join(TIMEOUT)
    done.set()
    assert engine.snapshot().stats.samples >= target


def test_engine_satisfies_the_handle_protocol(make_engine: MakeEngine) -> None:
    engine: EngineHandle = make_engine()
    assert engine.defaults().get("CONTROLLER ONE.K") == 3.0
    assert engine.par_names() == [] and not engine.log_exists("data")


def test_commands_go_through_futures_and_apply_between_samples(make_engine: MakeEngine) -> None:
    e = make_engine(clock="virtual", speed=None)
    e.start()
    assert e.running and e.loop.realtime is False
    assert e.submit(SetState("Run")).result(TIMEOUT).ok
    wait_samples(e, 100)
    fut = e.submit(SetParams({"REFERENCE ONE.Mean": 0.5}))
    assert fut.result(TIMEOUT).ok
    refused = e.submit(SetParams({"REFERENCE ONE.Mean": 9.0})).result(TIMEOUT)
    assert not refused.ok and "REFERENCE ONE.Mean" in refused.message
    wait_samples(e, 5)
    assert e.snapshot().u[0] == 0.5
    assert e.submit(SetSpeed(1000)).result(TIMEOUT).ok and e.snapshot().speed == 1000
    e.stop()


def test_the_loop_keeps_sampling_while_another_thread_is_busy(make_engine: MakeEngine) -> None:
    e = make_engine(clock="virtual", speed=None)
    e.start()
    e.submit(SetState("Run")).result(TIMEOUT)
    before = e.snapshot().stats.samples
    # A UI-like event loop whose handler hogs its thread (a slow frame, in pure Python).
    progress = []

    async def slow_frame() -> None:
        x = 0
        for i in range(3_000_000):
            x += i * i
            if i % 500_000 == 0:
                progress.append(e.snapshot().stats.samples)

    asyncio.run(slow_frame())
    after = e.snapshot().stats.samples
    e.stop()
    assert after > before
    assert progress == sorted(progress) and progress[-1] > progress[0]  # it sampled during the frame


def test_stop_is_clean_idempotent_and_leaves_the_pumps_at_0(make_engine: MakeEngine) -> None:
    e = make_engine(clock="virtual", speed=None)
    e.start()
    e.submit(SetParams({"REFERENCE ONE.Mean": 0.7})).result(TIMEOUT)
    e.submit(SetState("Run")).result(TIMEOUT)
    e.submit(LogOn()).result(TIMEOUT)
    wait_samples(e, 10)
    e.stop()
    e.stop()
    assert not e.running
    assert e.loop.sim.voltages == (0.0, 0.0)
    assert e.snapshot().state == "Pause" and not e.snapshot().log.active and e.snapshot().log.unsaved
    late = e.submit(SetState("Run")).result(TIMEOUT)
    assert not late.ok and "stopped" in late.message


def test_realtime_without_a_thread_waits_for_each_deadline(make_engine: MakeEngine) -> None:
    src = ManualClock(50.0)
    slept: list[float] = []

    def sleep(dt: float) -> None:
        slept.append(dt)
        src.sleep(dt + 0.0005)  # wakes half a millisecond late

    e = make_engine(clock="realtime", now=src.now, sleep=sleep)
    e.submit(SetState("Run"))
    e.step(10)
    s = e.snapshot()
    assert s.realtime and s.stats.samples == 10 and s.stats.overruns == 0
    assert s.stats.jitter_last == pytest.approx(0.0005) and s.stats.last_sample_wall == pytest.approx(50.9005)
    # Absolute deadlines: each wait is shortened by the previous wake-up's lateness.
    assert slept == pytest.approx([0.1] + [0.0995] * 8)
    src.advance(0.35)  # a stall: from 50.9005 to 51.2505, the sample due at 51.0 is late
    e.step(1)           # and the deadlines 51.1 and 51.2 went by without their samples
    stats = e.snapshot().stats
    assert (stats.overruns, stats.skipped) == (1, 2) and stats.jitter_last == pytest.approx(0.2505)
    assert e.clock.deadline() == pytest.approx(51.3)


def test_manual_mode_is_reproducible_even_when_paced(make_engine: MakeEngine) -> None:
    a, b = make_engine(), make_engine()
    for e in (a, b):
        e.submit(SetSpeed(100))
        e.submit(SetState("Run"))
        assert e.run_for(60.0) == 600
    assert a.snapshot() == b.snapshot() and a.snapshot().speed == 100


def test_build_engine_reads_a_par_by_path_or_name_and_seeds_the_prbs(make_engine: MakeEngine,
                                                                   tmp_path: Path) -> None:
    from quadtank_tui.core.parameters import PRESET
    from quadtank_tui.files.par import write_par

    (tmp_path / "params").mkdir()
    write_par(tmp_path / "params" / "mine.par", PRESET.with_value("CONTROLLER ONE.K", 1.25))
    by_name = make_engine(par="mine", seed=9)
    by_path = make_engine(par=str(tmp_path / "params" / "mine.par"))
    assert by_name.snapshot().params.get("CONTROLLER ONE.K") == 1.25
    assert by_path.snapshot().params.get("CONTROLLER ONE.K") == 1.25
    p = by_name.snapshot().params
    assert (p.get("REFERENCE ONE.Seed"), p.get("REFERENCE TWO.Seed")) == (9, 10)
    assert any("default.par" in w for w in by_name.warnings)  # no default.par in that folder
    with pytest.raises(ValueError, match="nope.par"):
        make_engine(par="nope.par")
    with pytest.raises(ValueError, match="clock"):
        make_engine(clock="sundial")


def test_a_fault_on_the_loop_thread_pauses_and_the_thread_lives_on(make_engine: MakeEngine) -> None:
    from quadtank_tui.engine.backend import BackendError
    from quadtank_tui.engine.commands import SetOperation

    class Dead:
        kind, description, alarms = "Active", "dead rig", ()

        def read_levels(self):  # type: ignore[no-untyped-def]
            raise BackendError("no reply from 127.0.0.1:5020")

        def write_pumps(self, u):  # type: ignore[no-untyped-def]
            raise AssertionError("never reached")

        def safe_state(self) -> None:
            raise OSError("still dead")  # safe_state must not raise; the loop copes anyway

        def close(self) -> None:
            pass

    e = make_engine(clock="virtual", speed=None, daq=Dead())
    e.start()
    assert e.submit(SetOperation("Active")).result(TIMEOUT).ok
    assert e.submit(SetState("Run")).result(TIMEOUT).ok
    wait_samples(e, 20)
    s = e.snapshot()
    assert e.running and s.state == "Pause" and s.fault == "dead rig: no reply from 127.0.0.1:5020"
    e.stop()
    assert e.crash is None


def test_a_stored_name_without_default_par_warns_once(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """default.par is read once; its warning is not repeated by the named file's load."""
    import shutil

    from quadtank_tui.engine.runner import load_parameters
    from quadtank_tui.files.par import ParStore

    shutil.copy(Path(__file__).resolve().parents[2] / "params" / "minphase.par", tmp_path)
    _, warnings = load_parameters("minphase", ParStore(tmp_path))
    assert warnings == (f"{tmp_path / 'default.par'} not found: using the built-in (preset) values",)


def test_a_command_ends_the_drivers_wait_and_is_applied_between_samples(make_engine: MakeEngine,
                                                                       poll: Callable[..., bool]) -> None:
    """A sample 10 s away is waited for on the event loop: a command (and a stop)
    from another thread is taken at once, not after the wait."""
    import time

    e = make_engine(clock="realtime")
    assert e.submit(SetParams({"SAMPLING TIME.TSamp": 10000})).result(TIMEOUT).ok
    e.start()
    assert poll(lambda: e.snapshot().stats.samples == 1, TIMEOUT, 0.001)  # the first sample is due at once
    t0 = time.monotonic()
    assert e.submit(SetParams({"REFERENCE ONE.Mean": 0.5})).result(TIMEOUT).ok
    assert e.snapshot().params.get("REFERENCE ONE.Mean") == 0.5 and e.snapshot().stats.samples == 1
    e.stop()
    assert not e.running and time.monotonic() - t0 < 5.0  # not the 10 s to the next sample


def test_the_driver_runs_inline_inside_a_running_event_loop(make_engine: MakeEngine) -> None:
    """run_for / step from a coroutine (the UI tests drive engines from Textual's
    loop): the driver without clients needs no event loop of its own."""
    e = make_engine()
    e.submit(SetState("Run"))

    async def drive() -> int:
        return e.run_for(1.0) + e.step(5).stats.samples

    assert asyncio.run(drive()) == 10 + 15
