"""The requirement figures of an exercise on signals built here by hand (a
first-order step response, a known overshoot), not by the code they test."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quadtank_tui.core.exercise import Requirement, judge, live_state, signal_figure

H = 1.0
T = np.arange(0.0, 400.0, H)
STEP_AT = 100  # sample index of the reference step
TAU = 20.0     # s, the first-order response's time constant


def first_order() -> dict[str, np.ndarray]:
    """r1 steps 0.5 -> 0.6 at t = 100 s; y1 follows as 1 - exp(-t/tau); loop 2 sits
    at 0.4 with a bump of 0.03 at 150 s; u1 at full scale for the 5 samples after the step."""
    r1 = np.where(T >= T[STEP_AT], 0.6, 0.5)
    since = np.clip(T - T[STEP_AT], 0.0, None)
    y1 = 0.5 + 0.1 * np.where(T >= T[STEP_AT], 1.0 - np.exp(-since / TAU), 0.0)
    r2 = np.full_like(T, 0.4)
    y2 = r2 + 0.03 * np.exp(-((T - 150.0) / 10.0) ** 2)
    u1 = np.full_like(T, 0.3)
    u1[STEP_AT:STEP_AT + 5] = 1.0
    return {"t": T, "r1": r1, "y1": y1, "r2": r2, "y2": y2, "u1": u1, "u2": np.full_like(T, 0.3),
            "y3": np.full_like(T, 0.1), "y4": 0.2 + 0.001 * T}


def figure(kind: str, **kw: object) -> float | None:
    return signal_figure(Requirement(kind, 1.0, **kw), first_order(), H)[0]  # type: ignore[arg-type]


def test_first_order_step_figures() -> None:
    # settling in the 2 % band: exp(-t/tau) <= 0.02 from t = tau ln 50 = 78.2 s, the next whole sample 79 s
    assert figure("settling_time", loop=1) == pytest.approx(math.ceil(TAU * math.log(50.0)))
    # 5 % band: tau ln 20 = 59.9 s
    assert figure("settling_time", loop=1, band=0.05) == pytest.approx(math.ceil(TAU * math.log(20.0)))
    # rise 10-90 %: tau (ln 10 - ln 10/9) = tau ln 9 = 43.9 s; on whole samples 47 - 3 = 44 s
    assert figure("rise_time", loop=1) == pytest.approx(math.ceil(TAU * math.log(10)) - math.ceil(TAU * math.log(10 / 9)))
    assert figure("overshoot", loop=1) == 0.0
    # IAE from the step: 0.1 x sum exp(-k/tau) over the samples (rectangles), ~0.1 tau
    expected = 0.1 * sum(math.exp(-k / TAU) for k in range(len(T) - STEP_AT))
    assert figure("iae", loop=1) == pytest.approx(expected, rel=1e-9)
    assert figure("steady_state_error", loop=1) == pytest.approx(0.1 * math.exp(-(len(T) - 1 - STEP_AT) / TAU))


def test_coupling_levels_and_pump_limit() -> None:
    assert figure("coupling", loop=1) == pytest.approx(0.03)          # the bump in loop 2
    assert figure("max_level", tank=4) == pytest.approx(0.2 + 0.001 * T[-1])
    assert figure("pump_limit_time") == 5.0                            # 5 samples of 1 s at full scale
    assert signal_figure(Requirement("coupling", 1.0, loop=2), first_order(), H) == (
        None, "no step of r2 in the log")


def test_an_overshoot_of_a_known_size() -> None:
    cols = first_order()
    cols["y1"] = cols["y1"].copy()
    cols["y1"][STEP_AT + 30] = 0.6 + 0.1 * 0.123  # 12.3 % of the step above the new reference
    fig, _ = signal_figure(Requirement("overshoot", 10.0, loop=1), cols, H)
    assert fig == pytest.approx(12.3)
    v = judge(Requirement("overshoot", 10.0, loop=1), fig)
    assert not v.met and v.figure_text() == "12.3 %"


def test_verdicts_and_live_states() -> None:
    over = Requirement("overshoot", 10.0, loop=1)
    margin = Requirement("phase_margin", 45.0, loop=1)
    settle = Requirement("settling_time", 60.0, loop=1)
    assert judge(margin, 50.0).met and not judge(margin, 40.0).met
    assert not judge(settle, None, "not settled by the end").met
    assert live_state(over, 12.0, finished=False) == "missed"     # overshoot only grows
    assert live_state(over, 5.0, finished=False) == "pending"
    assert live_state(settle, 70.0, finished=False) == "pending"  # a settling time waits for the end
    assert live_state(settle, 50.0, finished=True) == "met"
    assert live_state(settle, None, finished=True) == "missed"


def test_a_missing_column_is_named() -> None:
    cols = first_order()
    del cols["y4"]
    with pytest.raises(ValueError, match="max_level 4: the log has no y4 column"):
        signal_figure(Requirement("max_level", 1.0, tank=4), cols, H)
