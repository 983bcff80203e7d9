"""The controller type "MPC" in the loop (engine/mpc_control.py), on the nonlinear
quadruple tank at P- with the loop's virtual time.

Levels in cm are y * 20 (kc = 0.5 V/cm); pumps 0..10 V are u in 0..1.
"""

from __future__ import annotations

import numpy as np
import pytest

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.engine.commands import Command, SetControlMode, SetFault, SetParams, SetState
from quadtank_tui.engine.loop import ControlLoop

CM = 20.0  # cm per normalized unit
BUMP = 0.005  # largest pump jump at a switch sample, of full scale (measured 0.002)


def ok(loop: ControlLoop, command: Command) -> None:
    result = loop.apply(command)
    assert result.ok, result.message


def run(loop: ControlLoop, samples: int) -> np.ndarray:
    """Rows (y1..y4, u1, u2, r1, r2) of `samples` samples."""
    return np.array([(*s.y, *s.u, *s.r) for s in (loop.step() for _ in range(samples))])


def settled_pi(leak: float = 0.0, samples: int = 1500) -> ControlLoop:
    """The preset's PI loop in Automatic, settled at levels off the operating point
    (with a leak in tank 1 of `leak` cm^2: a plant the MPC's model does not know)."""
    loop = ControlLoop(PRESET)
    ok(loop, SetState("Run"))
    if leak:
        ok(loop, SetFault("leak", 1, leak))
    ok(loop, SetParams({"REFERENCE ONE.Mean": 0.33}))  # Manual: a pump step, then PI
    run(loop, 300)
    ok(loop, SetControlMode("Automatic"))
    run(loop, samples)
    return loop


def test_pi_to_mpc_and_back_is_bumpless_and_mpc_tracks_a_step_within_the_pumps() -> None:
    loop = settled_pi()
    before = loop.snapshot().u
    ok(loop, SetParams({"CONTROL.Type": "MPC"}))
    assert loop.controllers.mpc is not None and loop.statefb is None
    after = loop.step().u
    assert np.abs(np.subtract(after, before)).max() < BUMP, (before, after)
    r1 = loop.snapshot().r[0] + 1.0 / CM  # +1 cm on loop 1, announced by the generator
    ok(loop, SetParams({"REFERENCE ONE.Mean": r1}))
    rows = run(loop, 400)  # 40 s at h = 0.1 s
    assert np.all((rows[:, 4:6] >= 0.0) & (rows[:, 4:6] <= 1.0))
    assert np.any(rows[:, 4:6] > after[0] + 0.05)  # it acted
    assert rows[-1, 0] * CM == pytest.approx(r1 * CM, abs=0.02)  # within 0.02 cm after 40 s
    assert rows[-1, 1] == pytest.approx(rows[-1, 7], abs=0.02 / CM)
    snap = loop.snapshot()
    assert snap.mpc is not None and snap.mpc.solves == 401 and snap.mpc.faults == 0
    assert snap.mpc.status == "solved" and 0.0 < snap.mpc.p50_ms <= snap.mpc.p99_ms <= snap.mpc.max_ms
    before = snap.u
    ok(loop, SetParams({"CONTROL.Type": "PID"}))
    after = loop.step().u
    assert loop.controllers.mpc is None and loop.snapshot().mpc is None
    assert np.abs(np.subtract(after, before)).max() < BUMP, (before, after)


def test_the_switch_is_bumpless_on_a_plant_the_model_does_not_know() -> None:
    """A leak of 0.15 a1 in tank 1: the MPC starts with the disturbance that holds the
    measured levels under the pumps in force (jump 0.0018); started with none, its
    first move jumped 0.072 towards the model's steady input."""
    loop = settled_pi(leak=0.15 * 0.071, samples=3000)
    before = loop.snapshot().u
    ok(loop, SetParams({"CONTROL.Type": "MPC"}))
    rows = run(loop, 20)
    assert np.abs(rows[0, 4:6] - before).max() < BUMP and np.abs(np.diff(rows[:, 4:6], axis=0)).max() < BUMP


def test_the_switch_is_bumpless_while_the_levels_still_move() -> None:
    """5 s after a 2-cm step on loop 1 (1 cm still to go) the PI is switched to MPC:
    the estimate is chosen so the first move is the pumps in force (jump 6e-15 of
    full scale; before, 0.49 with RateWeight 0 and 0.085 with 0.3), and the MPC then
    takes over at most 0.015 a sample (its own answer to the error, as the Kalman
    filter moves the estimate) and brings loop 1 to its reference.  The bound on the
    jump is 1e-6 of full scale (10 uV)."""
    loop = settled_pi(samples=300)
    assert loop.params.mpc.rate_weight == 0.0  # nothing holds the first move back but the start
    ok(loop, SetParams({"REFERENCE ONE.Mean": loop.snapshot().r[0] + 2.0 / CM}))
    run(loop, 50)
    assert (loop.snapshot().r[0] - loop.snapshot().y[0]) * CM > 0.9  # on its way
    before = loop.snapshot().u
    ok(loop, SetParams({"CONTROL.Type": "MPC"}))
    rows = run(loop, 250)
    assert np.abs(rows[0, 4:6] - before).max() < 1e-6
    assert np.abs(np.diff(rows[:, 4:6], axis=0)).max() < 0.02
    assert rows[-1, 0] == pytest.approx(rows[-1, 6], abs=0.1 / CM)


def test_a_failing_solve_holds_the_last_input_and_is_counted_in_the_snapshot(monkeypatch: pytest.MonkeyPatch) -> None:
    loop = settled_pi()
    ok(loop, SetParams({"CONTROL.Type": "MPC"}))
    run(loop, 5)
    mpc = loop.controllers.mpc
    assert mpc is not None
    held = loop.snapshot().u

    def broken(*_: object) -> object:
        raise RuntimeError("solver crashed")

    monkeypatch.setattr(mpc.mpc.qp, "solve", broken)
    rows = run(loop, 3)
    assert rows[:, 4:6] == pytest.approx(np.tile(held, (3, 1)))
    snap = loop.snapshot()
    assert snap.mpc is not None and snap.mpc.faults == 3 and snap.mpc.solves == 8
    assert snap.mpc.status == "RuntimeError: solver crashed" and snap.state == "Run"


def test_a_bad_mpc_setting_is_refused_and_nothing_changes() -> None:
    loop = ControlLoop(PRESET.with_values({"CONTROL.Type": "MPC"}))
    assert loop.controllers.mpc is not None
    was = loop.params
    result = loop.apply(SetParams({"MPC.Horizon": 10, "MPC.ControlHorizon": 20}))
    assert not result.ok and "ControlHorizon" in result.message
    assert loop.params is was and loop.controllers.mpc.horizon == 30


def _before_a_reference_edge(preview: int) -> float:
    """How far u1 moved over the 5 s before a square wave's edge on r1 (h = 0.5 s: the
    horizon sees 15 s ahead)."""
    loop = ControlLoop(PRESET.with_values({"CONTROL.Type": "MPC", "MPC.Preview": preview,
                                           "SAMPLING TIME.TSamp": 500}))
    ok(loop, SetState("Run"))
    ok(loop, SetControlMode("Automatic"))
    ok(loop, SetParams({"REFERENCE ONE.On": 1, "REFERENCE ONE.Amplitude": 0.02, "REFERENCE ONE.Period": 20.0}))
    rows = run(loop, 25)
    edge = int(np.flatnonzero(np.abs(np.diff(rows[:, 6])) > 0.01)[-1]) + 1  # first sample at the new r1
    return float(np.ptp(rows[edge - 10:edge, 4]))  # 5 s


def test_with_preview_the_mpc_moves_before_the_reference_does() -> None:
    """The wave is known ahead: with Preview the pumps start within the horizon
    before the edge; without it they wait for it."""
    assert _before_a_reference_edge(1) > 0.1  # measured 0.18
    assert _before_a_reference_edge(0) < 0.03  # 0.015: the settling after the wave's first edge


def test_a_design_made_off_the_loop_is_installed_and_keeps_the_counts() -> None:
    """engine/design_ahead.py: which SetParams need a new MPC design, and the one
    designed elsewhere is the one installed (a redesign keeps the solve counts)."""
    from quadtank_tui.engine.controllers import mpc_inputs, new_mpc
    from quadtank_tui.engine.design_ahead import needs_mpc_design

    loop = ControlLoop(PRESET)
    assert needs_mpc_design(loop, SetParams({"CONTROL.Type": "MPC"})) is not None
    assert needs_mpc_design(loop, SetParams({"CONTROLLER ONE.K": 2.0})) is None
    ok(loop, SetParams({"CONTROL.Type": "MPC"}))
    ok(loop, SetState("Run"))
    ok(loop, SetControlMode("Automatic"))
    run(loop, 5)
    info = loop.snapshot().mpc
    assert info is not None and info.solves == 5
    assert needs_mpc_design(loop, SetParams({"REFERENCE ONE.Mean": 0.4})) is None  # same design
    assert needs_mpc_design(loop, SetParams({"MPC.Horizon": 0})) is None  # refused where applied
    new = needs_mpc_design(loop, SetParams({"MPC.Horizon": 20}))
    assert new is not None
    designed = new_mpc(new)
    loop.controllers.offer(mpc_inputs(new), designed)
    ok(loop, SetParams({"MPC.Horizon": 20}))
    assert loop.controllers.mpc is designed and designed.horizon == 20
    run(loop, 1)
    info = loop.snapshot().mpc
    assert info is not None and info.solves == 6
