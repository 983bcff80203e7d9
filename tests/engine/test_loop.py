"""The loop's modes and commands (product.md M1-M3, M8; issue 5, "Tests that must hold")."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.core.controllers.matrix import Family, Structure
from quadtank_tui.core.parameters import PRESET
from quadtank_tui.engine.backend import BackendError, Pair, ProcessBackend
from quadtank_tui.engine.commands import (
    AddWater, Command, LoadPar, LogDiscard, LogOff, LogOn, LogSave, NudgeMean, ResetControllers, SavePar,
    SetControlMode, SetDefaults, SetOperation, SetParams, SetSpeed, SetState,
)
from quadtank_tui.engine.loop import ControlLoop
from quadtank_tui.engine.runner import Engine
from quadtank_tui.files.log_reader import read_log

MakeEngine = Callable[..., Engine]


def ok(engine: Engine, command: Command) -> None:
    result = engine.submit(command).result()
    assert result.ok, result.message


def test_start_up_is_simul_pause_manual(make_engine: MakeEngine) -> None:
    s = make_engine().snapshot()
    assert (s.operation, s.state, s.control) == ("Simul", "Pause", "Manual")
    assert s.y == pytest.approx((0.62, 0.635, 0.09, 0.07))
    assert not s.active_available and s.backend == "simulator"


def test_manual_drives_the_pumps_with_the_generators(make_engine: MakeEngine) -> None:
    e = make_engine()
    ok(e, SetParams({"REFERENCE ONE.Mean": 0.35, "REFERENCE TWO.Mean": 0.25}))
    ok(e, SetState("Run"))
    s = e.step(3)
    assert s.u == (0.35, 0.25) and s.k == 3 and s.t == pytest.approx(0.3)
    assert s.r == (s.y[0], s.y[1]) or s.k > 0  # r follows y in Manual
    hist = e.history()
    assert hist["u1"].tolist() == [0.35] * 3 and hist["t"].tolist() == pytest.approx([0.0, 0.1, 0.2])


def test_pause_freezes_the_simulated_levels(make_engine: MakeEngine) -> None:
    e = make_engine()
    ok(e, SetParams({"REFERENCE ONE.Mean": 0.6}))
    ok(e, SetState("Run"))
    e.step(50)
    ok(e, SetState("Pause"))
    frozen = e.step(1)  # shows the levels as the last Run sample left them
    e.step(200)
    s = e.snapshot()
    assert s.y == frozen.y and s.t == frozen.t and s.k == frozen.k and s.state == "Pause"
    assert len(e.history()["t"]) == 50
    ok(e, SetState("Run"))
    assert e.step(1).y == frozen.y and e.step(1).y != frozen.y  # read, then time passes again


def test_reset_returns_to_the_operating_point_and_pauses(make_engine: MakeEngine) -> None:
    e = make_engine()
    ok(e, SetParams({"REFERENCE ONE.Mean": 0.8, "REFERENCE TWO.Mean": 0.1}))
    ok(e, SetState("Run"))
    e.step(300)
    ok(e, SetControlMode("Automatic"))
    e.step(100)
    assert e.loop.matrix._pid[(1, 1)].integral_state != 0.0
    ok(e, SetState("Reset"))
    s = e.snapshot()
    assert s.state == "Pause" and s.t == 0.0 and s.k == 0
    assert s.y == pytest.approx((0.62, 0.635, 0.09, 0.07), abs=1e-12)
    assert e.loop.sim.levels_cm == pytest.approx(PRESET.operating_levels())
    assert e.loop.matrix._pid[(1, 1)].integral_state == 0.0
    assert len(e.history()["t"]) == 0


def test_manual_to_automatic_is_bumpless_on_the_logged_u(make_engine: MakeEngine, tmp_path: Path) -> None:
    e = make_engine()
    ok(e, SetParams({"LOGGING.Variables": "t y1 y2 u1 u2 r1 r2", "LOGGING.Points": 400}))
    ok(e, SetParams({"REFERENCE ONE.Mean": 0.32, "REFERENCE TWO.Mean": 0.28}))
    ok(e, SetState("Run"))
    e.step(100)
    ok(e, LogOn())
    e.step(100)
    y_switch = e.snapshot().y
    ok(e, SetControlMode("Automatic"))
    p = e.snapshot().params
    # Reference means := the measured levels.
    assert p.get("REFERENCE ONE.Mean") == y_switch[0] and p.get("REFERENCE TWO.Mean") == y_switch[1]
    assert p.get("CONTROL.Mode") == "Automatic"
    e.step(100)
    ok(e, LogSave())
    log = read_log(tmp_path / "logs" / "data.log")
    u1, u2 = log["u1"], log["u2"]
    # Before the switch u is the constant input; right after, it moves only by what
    # the (tiny, drifting) error causes: far below a bump of the manual-to-auto kind.
    assert u1[99] == 0.32 and abs(u1[100] - u1[99]) < 2e-4 and abs(u2[100] - u2[99]) < 2e-4
    assert log["r1"][100] == pytest.approx(y_switch[0], abs=1e-6)

    # And back: input means := the applied inputs.
    u_now = e.snapshot().u
    ok(e, SetControlMode("Manual"))
    p = e.snapshot().params
    assert (p.get("REFERENCE ONE.Mean"), p.get("REFERENCE TWO.Mean")) == u_now
    assert e.step(1).u == u_now


@pytest.mark.parametrize("values", [
    {"CONTROLLER ONE.K": 2.0, "CONTROLLER ONE.Nope": 1.0},   # unknown key
    {"CONTROLLER ONE.K": 2.0, "SIMULATION.Valve1": 1.5},     # out of range
    {"CONTROLLER ONE.K": "fast"},                            # not a number
    {"REFERENCE ONE.Wave": "Sine", "REFERENCE ONE.Period": 0.1},  # too short for TSamp
    {"CONTROL.Mode": "Cruise"},
])
def test_a_bad_command_is_refused_and_changes_nothing(make_engine: MakeEngine, values: dict) -> None:
    e, twin = make_engine(), make_engine()
    for engine in (e, twin):
        ok(engine, SetState("Run"))
        engine.step(20)
    before = e.snapshot()
    result = e.submit(SetParams(values)).result()
    assert not result.ok and result.message
    assert e.snapshot().params == before.params
    assert e.step(30) == twin.step(30)


def test_other_refusals_name_the_reason(make_engine: MakeEngine) -> None:
    e = make_engine()
    refused: list[tuple[Command, str]] = [
        (SetOperation("Active"), "DAQ"), (NudgeMean(3, 0.1), "channel"), (AddWater(7, 0.1), "tank"),
        (LogOff(), "not on"), (LogSave(), "nothing"), (ResetControllers((3, 1)), "11, 12, 21, 22"),
        (LoadPar("missing"), "missing"),
    ]
    for command, words in refused:
        result = e.submit(command).result()
        assert not result.ok and words in result.message, (command, result.message)
    realtime = make_engine(clock="realtime")
    assert "virtual" in realtime.submit(SetSpeed(10)).result().message


class FlakyBackend(ProcessBackend):
    kind = "Active"
    description = "flaky rig"

    def __init__(self, fail_after: int, error: Exception) -> None:
        self.reads = 0
        self.fail_after = fail_after
        self.error = error
        self.pumps: Pair = (0.5, 0.5)
        self.safe_calls = 0
        self.alarms = ("tank 3 high",)

    def read_levels(self):
        self.reads += 1
        if self.reads > self.fail_after:
            raise self.error
        return (0.6, 0.6, 0.1, 0.1)

    def write_pumps(self, u: Pair) -> None:
        self.pumps = u

    def safe_state(self) -> None:
        self.safe_calls += 1
        self.pumps = (0.0, 0.0)


@pytest.mark.parametrize("error, reason", [
    (BackendError("read of AIN0 timed out after 2 tries"), "flaky rig: read of AIN0 timed out after 2 tries"),
    (ZeroDivisionError("division by zero"), "flaky rig: ZeroDivisionError: division by zero"),
])
def test_a_backend_that_raises_puts_the_pumps_at_0_and_pauses(
        make_engine: MakeEngine, error: Exception, reason: str) -> None:
    daq = FlakyBackend(fail_after=5, error=error)
    e = make_engine(daq=daq)
    ok(e, SetOperation("Active"))
    ok(e, SetParams({"REFERENCE ONE.Mean": 0.4}))
    ok(e, SetState("Run"))
    e.step(5)
    assert daq.pumps == (0.4, 0.3)
    s = e.step(1)  # the 6th read raises
    assert daq.pumps == (0.0, 0.0) and daq.safe_calls == 1
    assert s.state == "Pause" and s.fault == reason and s.operation == "Active"
    assert s.alarms == ("tank 3 high",)
    e.step(3)  # nothing escapes while paused on a dead link either
    assert e.snapshot().fault == reason
    ok(e, SetState("Run"))
    assert e.snapshot().fault is None


def test_pause_on_a_real_process_commands_the_pumps_to_0(make_engine: MakeEngine) -> None:
    daq = FlakyBackend(fail_after=10**9, error=BackendError("x"))
    e = make_engine(daq=daq)
    ok(e, SetOperation("Active"))
    ok(e, SetState("Run"))
    e.step(2)
    ok(e, SetState("Pause"))
    assert daq.pumps == (0.0, 0.0)
    e.step(2)
    assert daq.pumps == (0.0, 0.0)
    assert e.submit(AddWater(1, 0.1)).result().message.startswith("water can be added")


def test_sampling_time_change_is_bumpless_and_logging_guards_it(make_engine: MakeEngine) -> None:
    e = make_engine()
    ok(e, SetState("Run"))
    e.step(200)
    ok(e, SetControlMode("Automatic"))
    ok(e, NudgeMean(1, 0.05))
    e.step(200)
    u_before = e.snapshot().u
    ok(e, SetParams({"SAMPLING TIME.TSamp": 500}))
    assert e.clock.period == 0.5 and e.loop.h == 0.5
    u_after = e.step(1).u
    assert abs(u_after[0] - u_before[0]) < 5e-3 and abs(u_after[1] - u_before[1]) < 5e-3
    t = e.snapshot().t
    e.step(2)
    assert e.snapshot().t == pytest.approx(t + 1.0)
    ok(e, LogOn())
    refused = e.submit(SetParams({"SAMPLING TIME.TSamp": 100})).result()
    assert not refused.ok and "LogOff" in refused.message


def test_family_switch_resets_the_controllers_structure_switch_keeps_them(make_engine: MakeEngine) -> None:
    e = make_engine()
    ok(e, SetState("Run"))
    e.step(50)
    ok(e, SetControlMode("Automatic"))
    e.step(50)
    m = e.loop.matrix
    i11 = m._pid[(1, 1)].integral_state
    assert i11 != 0.0
    ok(e, SetParams({"CONTROL.Structure": "FullMatrix"}))
    assert m.structure is Structure.FULL_MATRIX and m._pid[(1, 1)].integral_state == i11
    ok(e, SetParams({"CONTROL.Type": "General"}))
    assert m.family is Family.GENERAL and m._pid[(1, 1)].integral_state == 0.0


def test_nudge_add_water_defaults_and_controller_reset(make_engine: MakeEngine) -> None:
    e = make_engine()
    ok(e, NudgeMean(2, 0.1))
    assert e.snapshot().params.get("REFERENCE TWO.Mean") == pytest.approx(0.4)
    ok(e, AddWater(2, 0.05))
    assert e.snapshot().y[1] == pytest.approx(0.685)
    ok(e, SetParams({"CONTROLLER ONE.K": 9.0}))
    ok(e, SetDefaults(("CONTROLLER ONE.K",)))
    assert e.snapshot().params.get("CONTROLLER ONE.K") == 3.0
    ok(e, ResetControllers((1, 1)))
    ok(e, ResetControllers())


def test_log_on_off_save_discard(make_engine: MakeEngine, tmp_path: Path) -> None:
    e = make_engine()
    ok(e, SetParams({"LOGGING.Points": 10, "LOGGING.LogFile": "run1"}))
    ok(e, SetState("Run"))
    ok(e, LogOn())
    e.step(25)
    s = e.snapshot().log
    assert (s.active, s.rows, s.points, s.unsaved, s.progress) == (False, 10, 10, True, 1.0)
    assert (tmp_path / "logs" / "run1.log.partial").exists()
    ok(e, LogSave())
    assert read_log(tmp_path / "logs" / "run1.log").rows == 10
    ok(e, LogOn())
    e.step(3)
    refused = e.submit(LogSave()).result()
    assert not refused.ok and "exists" in refused.message
    ok(e, LogDiscard())
    assert not (tmp_path / "logs" / "run1.log.partial").exists()
    assert read_log(tmp_path / "logs" / "run1.log").rows == 10


def test_par_files_save_and_load(make_engine: MakeEngine, tmp_path: Path) -> None:
    e = make_engine()
    ok(e, SetParams({"CONTROLLER ONE.K": 2.5}))
    ok(e, SavePar("mine"))
    assert e.par_names() == ["mine"]
    assert not e.submit(SavePar("mine")).result().ok
    assert not e.submit(SavePar("default")).result().ok
    ok(e, SetParams({"CONTROLLER ONE.K": 1.0}))
    result = e.submit(LoadPar("mine")).result()
    assert result.ok and e.snapshot().params.get("CONTROLLER ONE.K") == 2.5
    assert e.loop.matrix.pid_params(1, 1).K == 2.5
    ok(e, LoadPar("preset"))
    assert e.snapshot().params.get("CONTROLLER ONE.K") == 3.0


def test_the_loop_alone_is_deterministic() -> None:
    a, b = ControlLoop(PRESET), ControlLoop(PRESET)
    for loop in (a, b):
        loop.apply(SetParams({"REFERENCE ONE.On": 1, "REFERENCE ONE.Wave": "PRBS",
                              "REFERENCE ONE.Period": 5, "REFERENCE ONE.Amplitude": 0.05}))
        loop.apply(SetState("Run"))
        for _ in range(500):
            loop.step()
    assert a.snapshot() == b.snapshot()


@pytest.mark.parametrize("values", [
    {"SAMPLING TIME.TSamp": 2000, "REFERENCE ONE.Wave": "Sine", "REFERENCE ONE.Period": 10},
    {"SAMPLING TIME.TSamp": 50, "REFERENCE ONE.Wave": "Sine", "REFERENCE ONE.Period": 0.15},
])
def test_sampling_time_and_period_change_together(make_engine: MakeEngine, values: dict) -> None:
    e = make_engine()
    ok(e, SetParams({"REFERENCE ONE.Wave": "Sine", "REFERENCE ONE.Period": 3.0, "REFERENCE ONE.On": 1}))
    ok(e, SetState("Run"))
    e.step(5)
    ok(e, SetParams(values))  # valid together; the old period at the new TSamp (or the new
    # period at the old TSamp) is not, so the generator must take them in the right order
    assert e.loop.h == values["SAMPLING TIME.TSamp"] / 1000 and e.clock.period == e.loop.h
    e.step(5)
    assert e.snapshot().fault is None
