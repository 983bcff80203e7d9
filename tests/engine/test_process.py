"""The loop in its own process: the same results as in-process, through the same
handle; refusals, a bad file, and either side dying leave things safe and said."""

from __future__ import annotations

import functools
import multiprocessing
import os
import signal
import time
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

from quadtank_tui.engine.commands import (
    LogOn, SetControlMode, SetParams, SetState,
)
from quadtank_tui.engine.process import EngineProcess
from quadtank_tui.engine.runner import Engine, build_engine, engine_spec
from quadtank_tui.files.par import ParFileError

pytestmark = pytest.mark.wallclock  # a real loop process, real timeouts

COMMANDS = (
    SetParams({"REFERENCE ONE.On": 1, "REFERENCE ONE.Amplitude": 0.05, "REFERENCE ONE.Period": 4}),
    SetState("Run"),
    SetControlMode("Automatic"),
)


def mark_safe_state(path: str, engine: Engine) -> None:
    """A setup hook (runs in the loop process): the simulator's safe_state leaves a
    file behind, so the test sees that the pumps were put at 0."""
    sim = engine.loop.sim
    original = sim.safe_state

    def safe_state() -> None:
        Path(path).write_text("pumps at 0\n")
        original()

    sim.safe_state = safe_state  # type: ignore[method-assign]


def wait_for(condition: Callable[[], bool], timeout: float = 60.0) -> None:
    end = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > end:
            raise AssertionError("timed out")
        time.sleep(0.01)


@pytest.fixture
def spawn(tmp_path: Path) -> Callable[..., EngineProcess]:
    made: list[EngineProcess] = []

    def make(setup: Callable[[Engine], None] | None = None, **kwargs: object) -> EngineProcess:
        kwargs.setdefault("clock", "virtual")
        kwargs.setdefault("speed", 1000.0)
        kwargs.setdefault("params_dir", tmp_path / "params")
        kwargs.setdefault("logs_dir", tmp_path / "logs")
        engine = EngineProcess(engine_spec(**kwargs), setup=setup)  # type: ignore[arg-type]
        made.append(engine)
        return engine

    yield make
    for engine in made:
        engine.stop()


def test_the_loop_process_computes_exactly_what_the_in_process_engine_does(
        spawn: Callable[..., EngineProcess], tmp_path: Path) -> None:
    e = spawn()
    s = e.snapshot()
    assert (s.k, s.operation, s.state, s.control) == (0, "Simul", "Pause", "Manual")
    for command in COMMANDS:
        assert e.submit(command).result(timeout=10).ok
    assert e.snapshot().control == "Automatic"  # published before the result came back
    e.start()
    n = 400
    torn = []
    while e.snapshot().k < n:  # read the trends while the loop writes them
        t = e.history()["t"]
        if len(t) > 1 and not np.allclose(np.diff(t), 0.1, rtol=0, atol=1e-9):
            torn.append(t)
    e.stop()
    assert not torn
    final = e.snapshot()
    assert final.state == "Pause" and final.k >= n
    got = e.history()
    assert len(got["t"]) == final.k

    here = build_engine(clock="manual", params_dir=tmp_path / "params", logs_dir=tmp_path / "logs")
    for command in COMMANDS:
        here.submit(command)
    here.step(n)
    want = here.history()
    for name, column in want.items():
        assert np.array_equal(got[name][:n], column), name
    assert e.defaults() == here.defaults()


def test_a_refused_command_changes_nothing_and_the_parameters_keep_their_identity(
        spawn: Callable[..., EngineProcess]) -> None:
    e = spawn()
    before = e.snapshot()
    result = e.submit(SetParams({"CONTROLLER ONE.K": 2.0, "NO SUCH.Key": 1})).result(timeout=10)
    assert not result.ok and "NO SUCH.Key" in result.message
    after = e.snapshot()
    assert after.params is before.params  # unpickled once, kept while unchanged
    assert e.submit(SetParams({"CONTROLLER ONE.K": 2.0})).result(timeout=10).ok
    changed = e.snapshot()
    assert changed.params is not before.params and changed.params.get("CONTROLLER ONE.K") == 2.0


def test_a_bad_par_file_is_refused_before_any_process_starts(tmp_path: Path) -> None:
    bad = tmp_path / "bad.par"
    bad.write_text("CONTROLLER ONE\nK = three\n")
    with pytest.raises(ParFileError, match=r"bad\.par, line 2: .*K"):
        EngineProcess(engine_spec(bad, clock="virtual", params_dir=tmp_path, logs_dir=tmp_path))
    assert multiprocessing.active_children() == []


def test_the_loop_stops_with_the_pumps_at_0_when_the_ui_process_goes_away(
        spawn: Callable[..., EngineProcess], tmp_path: Path) -> None:
    marker = tmp_path / "safe"
    e = spawn(setup=functools.partial(mark_safe_state, str(marker)))
    for command in (*COMMANDS, LogOn()):
        assert e.submit(command).result(timeout=10).ok
    e.start()
    wait_for(lambda: e.snapshot().log.rows > 50)
    e._inbox.close()  # what the child sees of a parent killed or its SSH session lost
    e._proc.join(timeout=60)
    assert e._proc.exitcode == 0
    assert marker.read_text() == "pumps at 0\n"
    s = e.snapshot()  # this test's process is still here, and is told
    assert s.state == "Pause" and "stopped unexpectedly (exit code 0)" in (s.fault or "")
    assert s.log.unsaved and s.log.rows > 50  # LogOff'd, the rows kept for Save


def test_sigterm_stops_the_loop_in_order(spawn: Callable[..., EngineProcess], tmp_path: Path) -> None:
    marker = tmp_path / "safe"
    e = spawn(setup=functools.partial(mark_safe_state, str(marker)))
    for command in COMMANDS:
        e.submit(command)
    e.start()
    wait_for(lambda: e.snapshot().k > 10)
    os.kill(e._proc.pid, signal.SIGTERM)
    e._proc.join(timeout=60)
    assert e._proc.exitcode == 0 and marker.exists()


def test_a_dead_loop_process_is_shown_and_commands_are_refused(spawn: Callable[..., EngineProcess]) -> None:
    e = spawn()
    e.submit(SetState("Run"))
    e.start()
    wait_for(lambda: e.snapshot().k > 10)
    os.kill(e._proc.pid, signal.SIGKILL)
    wait_for(lambda: not e.running)
    s = e.snapshot()
    assert s.state == "Pause"
    assert s.fault is not None and "stopped unexpectedly" in s.fault and "-9" in s.fault
    result = e.submit(SetState("Run")).result(timeout=30)
    assert not result.ok and result.message == "the engine has stopped"
    e.stop()  # returns at once, no error


def test_no_shared_memory_file_is_left_behind(spawn: Callable[..., EngineProcess]) -> None:
    e = spawn()
    assert not Path(e._shared.block.path).exists()  # unlinked once both sides had it
    e.stop()


def test_stopped_engines_hold_no_descriptors_and_keep_their_last_picture(
        spawn: Callable[..., EngineProcess]) -> None:
    def fds() -> int:
        return len(os.listdir("/proc/self/fd"))

    kept = [spawn()]  # the first spawn sets up multiprocessing's own helpers
    kept[0].stop()
    before = fds()
    for _ in range(5):
        e = spawn()
        e.submit(SetState("Run"))
        e.start()
        wait_for(lambda: e.snapshot().k > 5)
        e.stop()
        kept.append(e)
    assert fds() == before
    last = kept[-1]
    assert last.snapshot().k > 5 and len(last.history()["t"]) >= 5
