"""The engine and its driver (engine/driver.py) inline: commands through futures,
clean stops, faults, deadlines.  The driver served on an event loop with clients is
tested with the session host (tests/session).

Counts, not timing: nothing here depends on how fast the machine is.
"""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.engine.clock import ManualClock
from quadtank_tui.engine.commands import LogOn, SetParams, SetSpeed, SetState
from quadtank_tui.engine.handle import EngineHandle
from quadtank_tui.engine.runner import Engine

MakeEngine = Callable[..., Engine]
TIMEOUT = 30.0


def test_engine_satisfies_the_handle_protocol(make_engine: MakeEngine) -> None:
    engine: EngineHandle = make_engine()
    assert engine.defaults().get("CONTROLLER ONE.K") == 3.0
    assert engine.par_names() == [] and not engine.log_exists("data")


def test_stop_is_clean_idempotent_and_leaves_the_pumps_at_0(make_engine: MakeEngine) -> None:
    e = make_engine()
    e.submit(SetParams({"REFERENCE ONE.Mean": 0.7})).result(0)
    e.submit(SetState("Run")).result(0)
    e.submit(LogOn()).result(0)
    e.step(10)
    assert e.loop.sim.voltages != (0.0, 0.0)
    e.stop()
    e.stop()
    assert e.loop.sim.voltages == (0.0, 0.0)
    assert e.snapshot().state == "Pause" and not e.snapshot().log.active and e.snapshot().log.unsaved
    late = e.submit(SetState("Run")).result(0)
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


def test_a_fault_pauses_and_the_driver_goes_on(make_engine: MakeEngine) -> None:
    from quadtank_tui.engine.backend import BackendError
    from quadtank_tui.engine.commands import SetOperation

    class Dead:
        kind, description, alarms = "Active", "dead rig", ()

        def read_levels(self):
            raise BackendError("no reply from 127.0.0.1:5020")

        def write_pumps(self, u):
            raise AssertionError("never reached")

        def safe_state(self) -> None:
            raise OSError("still dead")  # safe_state must not raise; the loop copes anyway

        def close(self) -> None:
            pass

    e = make_engine(clock="virtual", speed=None, daq=Dead())
    assert e.submit(SetOperation("Active")).result(0).ok
    assert e.submit(SetState("Run")).result(0).ok
    s = e.step(20)
    assert s.stats.samples == 20 and s.state == "Pause" and s.fault == "dead rig: no reply from 127.0.0.1:5020"
    e.stop()


def test_a_stored_name_without_default_par_warns_once(tmp_path) -> None:
    """default.par is read once; its warning is not repeated by the named file's load."""
    import shutil

    from quadtank_tui.engine.runner import load_parameters
    from quadtank_tui.files.par import ParStore

    shutil.copy(Path(__file__).resolve().parents[2] / "params" / "minphase.par", tmp_path)
    _, warnings = load_parameters("minphase", ParStore(tmp_path))
    assert warnings == (f"{tmp_path / 'default.par'} not found: using the built-in (preset) values",)


def test_the_driver_runs_inline_inside_a_running_event_loop(make_engine: MakeEngine) -> None:
    """run_for / step from a coroutine (the UI tests drive engines from Textual's
    loop): the driver without clients needs no event loop of its own."""
    e = make_engine()
    e.submit(SetState("Run"))

    async def drive() -> int:
        return e.run_for(1.0) + e.step(5).stats.samples

    assert asyncio.run(drive()) == 10 + 15
