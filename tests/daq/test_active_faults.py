"""Faults of the Active link through the engine: the loop pauses with the pumps
commanded to 0 and the reason in its snapshot, keeps the log, never raises, and runs
again only when the user says Run.  Against virtual-rig subprocesses on loopback."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.daq.config import Output
from quadtank_tui.daq.modbus import ModbusBackend
from quadtank_tui.daq.registers import Register
from quadtank_tui.engine.commands import Command, LogOn, LogSave, SetOperation, SetParams, SetState
from quadtank_tui.engine.runner import Engine, build_engine
from quadtank_tui.files.log_reader import read_log

ROOT = Path(__file__).parents[2]


def ok(engine: Engine, command: Command) -> None:
    result = engine.submit(command).result()
    assert result.ok, result.message


def active_engine(backend: ModbusBackend, tmp_path: Path, **kw: object) -> Engine:
    """An engine in Active on `backend`, paced at x20 unless told otherwise."""
    options: dict[str, object] = {"clock": "virtual", "speed": 20.0, **kw}
    engine = build_engine(None, daq=backend, params_dir=ROOT / "params",
                          logs_dir=tmp_path, **options)  # type: ignore[arg-type]
    ok(engine, SetOperation("Active"))
    return engine


def test_rig_killed_mid_run_then_resumed_by_the_user(rig: Callable, tmp_path: Path) -> None:
    r = rig("--speed", "20")
    backend = ModbusBackend(r.config())
    engine = active_engine(backend, tmp_path)
    try:
        ok(engine, LogOn())
        ok(engine, SetState("Run"))
        samples = engine.run_for(5.0)
        assert r.dacs() == pytest.approx((3.0, 3.0))  # u = 0.3 in Manual
        rows = engine.snapshot().log.rows
        # 50 sampling slots; at x20 (5 ms) a busy machine misses some, and the rig's
        # time does not wait: each sample taken is a row, each missed slot passed (the
        # last sample, if late, may carry the count past 50 by the slots it missed).
        assert rows == samples and 50 <= samples + engine.snapshot().stats.skipped <= 50 + engine.missed

        r.kill()
        snap = engine.step()                           # never raises
        assert snap.state == "Pause" and snap.operation == "Active"
        assert snap.fault is not None
        assert snap.fault.startswith(f"modbus 127.0.0.1:{r.port}: read of AIN0..AIN3 (input registers 0-7)")
        assert "failed twice" in snap.fault
        assert "cannot connect" in backend.safe_state_error  # pumps to 0 was attempted
        for _ in range(3):                             # paused: it keeps trying to show levels
            snap = engine.step()
            assert snap.state == "Pause" and snap.fault is not None
        ok(engine, LogSave("until-the-fault"))
        log = read_log(tmp_path / "until-the-fault.log")
        assert log.rows == rows and log.variables[:2] == ("y1", "y2")

        back = rig("--speed", "20", port=r.port)       # the link returns ...
        snap = engine.step()
        assert snap.state == "Pause"                   # ... and nothing restarts by itself
        assert back.dacs() == (0.0, 0.0)
        ok(engine, SetState("Run"))                    # the user resumes
        engine.run_for(2.0)
        snap = engine.snapshot()
        assert snap.state == "Run" and snap.fault is None
        assert back.dacs() == pytest.approx((3.0, 3.0))
    finally:
        engine.stop()


def test_a_fault_on_a_live_link_commands_the_pumps_to_zero(rig: Callable, tmp_path: Path) -> None:
    """Pump 2's output is configured at an address the device does not have: the
    sample's write fails, the engine pauses, and pump 1 (written separately) is
    commanded to 0 on the device although pump 2's output cannot be reached."""
    r = rig("--speed", "20")
    good = r.config()
    bad_dac1 = Output(Register("holding", 1010, "float32", "big"), (0.0, 10.0))
    config = dataclasses.replace(good, outputs={**good.outputs, "DAC1": bad_dac1})
    backend = ModbusBackend(config)
    engine = active_engine(backend, tmp_path)
    try:
        ok(engine, SetState("Run"))
        snap = engine.step()
        assert snap.state == "Pause"
        assert snap.fault is not None and "write of DAC1 (holding registers 1010-1011)" in snap.fault
        assert "the device answered 'illegal data address'" in snap.fault
        assert r.dacs()[0] == 0.0                      # pump 1 written 3 V, then 0 by safe_state
        assert "DAC1" in backend.safe_state_error and "DAC0" not in backend.safe_state_error
    finally:
        engine.stop()


def test_a_run_that_faults_at_once_leaves_no_guard_behind(
        rig: Callable, tmp_path: Path, poll: Callable[..., bool]) -> None:
    """The fault above at the first sample, pump 2's output unreachable (so the
    pumps to 0 also fails), then the end: the guard process the run started has
    ended within a few seconds of it, not with the program."""
    from quadtank_tui.files.proc import process_state

    r = rig("--speed", "20")
    good = r.config()
    config = dataclasses.replace(good, outputs={
        **good.outputs, "DAC1": Output(Register("holding", 1010, "float32", "big"), (0.0, 10.0))})
    backend = ModbusBackend(config)
    engine = active_engine(backend, tmp_path)
    try:
        ok(engine, SetState("Run"))
        assert engine.step().state == "Pause" and "DAC1" in backend.safe_state_error
        assert backend.guard is not None
        pid = backend.guard.pid
    finally:
        engine.stop()
    assert poll(lambda: process_state(pid) == "", 5.0), f"the guard (pid {pid}) outlived the run"


def test_pause_reset_and_exit_command_the_pumps_to_zero(rig: Callable, tmp_path: Path) -> None:
    r = rig("--speed", "20")
    engine = active_engine(ModbusBackend(r.config()), tmp_path)
    try:
        for leave in ("Pause", "Reset"):
            ok(engine, SetState("Run"))
            engine.run_for(0.5)
            assert r.dacs() == pytest.approx((3.0, 3.0))
            ok(engine, SetState(leave))
            assert r.dacs() == (0.0, 0.0), leave
        ok(engine, SetState("Run"))
        engine.run_for(0.5)
        assert r.dacs() == pytest.approx((3.0, 3.0))
    finally:
        engine.stop()                                 # Exit
    assert r.dacs() == (0.0, 0.0)


def test_a_rig_slower_than_the_sampling_time_counts_overruns(rig: Callable, tmp_path: Path) -> None:
    """Answers 80 ms late, a read and a write per 100 ms sample: every sample
    overruns, none fails (the timeout is longer than the delay)."""
    r = rig("--reply-delay", "0.08")
    engine = active_engine(ModbusBackend(r.config(timeout=1.0)), tmp_path, clock="realtime")
    try:
        ok(engine, SetState("Run"))
        # 2 s: arming the rig's watchdog at the first sample costs about ten requests
        # of 80 ms (the settings read, then written), slots skipped once; after it
        # every sample (a read and a write, 160 ms) starts late.
        engine.run_for(2.0)
        snap = engine.snapshot()
        assert snap.fault is None and snap.state == "Run"
        assert snap.stats.overruns >= 3
    finally:
        engine.stop()


def test_interlock_alarm_reaches_the_snapshot(rig: Callable, tmp_path: Path) -> None:
    r = rig("--speed", "20")
    engine = active_engine(ModbusBackend(r.config()), tmp_path)
    try:
        ok(engine, SetParams({"REFERENCE ONE.Mean": 0.95, "REFERENCE TWO.Mean": 0.2}))
        ok(engine, SetState("Run"))
        snap = engine.snapshot()
        for _ in range(1200):                         # at most 120 s of process time
            snap = engine.step()
            if snap.alarms:
                break
        assert snap.alarms == ("interlock: tank 1 above 95 % of its height, pump 1 cut",)
        assert snap.state == "Run" and snap.fault is None
        engine.step()
        assert r.dacs() == pytest.approx((0.0, 2.0))
    finally:
        engine.stop()
