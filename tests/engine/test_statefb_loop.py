"""The controller type "State feedback" in the loop, on the nonlinear quadruple tank.

Levels in cm are y * 20 (kc = 0.5 V/cm); pumps 0..10 V are u in 0..1.
"""

from __future__ import annotations

import numpy as np
import pytest

from quadtank_tui.core.parameters import PRESET, Parameters
from quadtank_tui.engine.commands import Command, ResetControllers, SetControlMode, SetParams, SetState
from quadtank_tui.engine.loop import ControlLoop

CM = 20.0  # cm per normalized unit


def ok(loop: ControlLoop, command: Command) -> None:
    result = loop.apply(command)
    assert result.ok, result.message


def run(loop: ControlLoop, samples: int) -> np.ndarray:
    """Rows (y1..y4, u1, u2, r1, r2) of `samples` samples."""
    rows = []
    for _ in range(samples):
        s = loop.step()
        rows.append((*s.y, *s.u, *s.r))
    return np.array(rows)


def statefb(**values: object) -> Parameters:
    return PRESET.with_values({"CONTROL.Type": "State feedback", **values})


def test_a_reference_step_series_tracks_with_zero_steady_state_error() -> None:
    loop = ControlLoop(statefb())
    ok(loop, SetState("Run"))
    run(loop, 50)
    ok(loop, SetControlMode("Automatic"))
    steps = ((14.0, 13.0), (11.0, 12.0), (12.4, 12.7))
    for r1, r2 in steps:
        ok(loop, SetParams({"REFERENCE ONE.Mean": r1 / CM, "REFERENCE TWO.Mean": r2 / CM}))
        rows = run(loop, 2500)  # 250 s; Ts = 60 s
        y_end = rows[-1, :2] * CM
        assert y_end == pytest.approx((r1, r2), abs=2e-3), (r1, r2, y_end)
        assert np.all(rows[-200:, 2:4] > 0)  # all four levels in use, upper tanks not empty


def test_switches_and_redesigns_are_bumpless() -> None:
    loop = ControlLoop(PRESET)
    ok(loop, SetState("Run"))
    ok(loop, SetParams({"REFERENCE ONE.Mean": 0.33}))  # Manual: a pump step, then PID
    run(loop, 300)
    ok(loop, SetControlMode("Automatic"))
    run(loop, 300)
    for change in ({"CONTROL.Type": "State feedback"},             # PID -> state feedback
                   {"STATE FEEDBACK.Ts": 90.0},                   # redesign
                   {"STATE FEEDBACK.Poles": "-0.05 -0.02"},       # poles typed in
                   {"SAMPLING TIME.TSamp": 200.0},                # new Phi, Gamma
                   {"CONTROL.Type": "PID"}):                      # and back
        before = loop.snapshot().u
        ok(loop, SetParams(change))
        after = loop.step().u
        assert after == pytest.approx(before, abs=2e-3), change
    assert loop.statefb is None


def test_the_snapshot_shows_gains_poles_and_delta() -> None:
    loop = ControlLoop(statefb())
    info = loop.snapshot().statefb
    assert info is not None and loop.statefb is not None
    d = loop.statefb.controller.design
    assert np.array(info.L1) == pytest.approx(d.L1) and np.array(info.L2) == pytest.approx(d.L2)
    assert len(info.poles_z) == 6 and info.delta == pytest.approx(d.delta)
    # "zeros": the P- plant's two slow zeros are among the poles, the rest Bessel (4.1.2)
    assert sorted(p.real for p in info.poles_s if p.imag == 0)[-2:] == pytest.approx([-0.0598, -0.0174], abs=1e-4)
    assert np.abs(np.array(info.poles_z) - d.poles_z).max() < 1e-9
    assert info.x_e[:2] == pytest.approx((12.4, 12.7)) and 0.5 <= info.delta < 1.0
    ok(loop, SetParams({"CONTROL.Type": "PID"}))
    assert loop.snapshot().statefb is None


@pytest.mark.parametrize(("values", "key"), [
    ({"STATE FEEDBACK.Poles": "-0.1+0.2j"}, "STATE FEEDBACK.Poles"),          # no conjugate
    ({"STATE FEEDBACK.Poles": "-1 -2 -3 -4 -5 -6 -7"}, "STATE FEEDBACK.Poles"),  # too many
    ({"STATE FEEDBACK.Level1": 2.0, "STATE FEEDBACK.Level2": 15.0}, "STATE FEEDBACK.Level1"),  # v1 < 0
    ({"STATE FEEDBACK.Ts": 0.5}, "STATE FEEDBACK.Ts"),
])
def test_a_design_there_is_none_of_is_refused_naming_the_key(values: dict, key: str) -> None:
    loop = ControlLoop(statefb())
    before = loop.snapshot()
    result = loop.apply(SetParams(values))
    assert not result.ok and key in result.message, result.message
    assert loop.snapshot().params == before.params


def _overshoot_from_empty(smart: bool) -> tuple[float, float, float]:
    """Fill the empty tanks to (12.4, 12.7) cm with Ts = 30 s: the pumps saturate.
    Returns the overshoots of y1, y2 (cm) and the fraction of samples at a limit."""
    loop = ControlLoop(statefb(**{"STATE FEEDBACK.Ts": 30.0, "STATE FEEDBACK.Smart": smart,
                                  "REFERENCE ONE.Mean": 0.0, "REFERENCE TWO.Mean": 0.0}))
    loop.place_at_steady_state((0.0, 0.0, 0.0, 0.0))
    ok(loop, SetState("Run"))
    run(loop, 10)
    ok(loop, SetControlMode("Automatic"))
    ok(loop, SetParams({"REFERENCE ONE.Mean": 0.62, "REFERENCE TWO.Mean": 0.635}))
    rows = run(loop, 2000)
    over = rows[:, :2].max(axis=0) * CM - (12.4, 12.7)
    limited = float(np.mean((rows[:, 4:6] >= 1.0) | (rows[:, 4:6] <= 0.0)))
    return float(over[0]), float(over[1]), limited


def test_the_smart_integrator_overshoots_less_than_the_plain_one_when_the_pumps_saturate() -> None:
    smart, plain = _overshoot_from_empty(True), _overshoot_from_empty(False)
    msg = f"overshoot y1, y2 (cm), fraction of samples at a pump limit: smart {smart}, plain {plain}"
    assert smart[2] > 0.01 and plain[2] > 0.01, msg  # the pump limit is active in both
    assert max(smart[:2]) < 1.0 < 3.0 < max(plain[:2]), msg
    assert smart[0] < plain[0] and smart[1] < plain[1], msg


def test_controller_reset_clears_the_integrators() -> None:
    loop = ControlLoop(statefb())
    ok(loop, SetState("Run"))
    ok(loop, SetControlMode("Automatic"))
    ok(loop, SetParams({"REFERENCE ONE.Mean": 0.7}))
    run(loop, 100)
    assert loop.statefb is not None and np.any(loop.statefb.controller.x_a != 0)
    ok(loop, ResetControllers())
    assert np.all(loop.statefb.controller.x_a == 0)


def test_a_file_asking_for_a_design_there_is_none_of_starts_with_pid_and_says_why() -> None:
    p = statefb(**{"STATE FEEDBACK.Level1": 2.0, "STATE FEEDBACK.Level2": 15.0})
    loop = ControlLoop(p)
    s = loop.snapshot()
    assert s.params.control.family.value == "PID" and loop.statefb is None
    assert s.fault is not None and "State feedback" in s.fault and "Level1" in s.fault
