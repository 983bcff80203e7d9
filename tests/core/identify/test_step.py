"""Andersson's five step-response structures: closed forms, FindSteps, the fit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from quadtank_tui.core.identify import IdentificationError
from quadtank_tui.core.identify.step import StepModel, find_steps, fit_step, simulate_steps

H = 1.0
N = 600
#: Three steps of different sizes and signs: the responses superpose.
U = np.zeros(N)
U[50:], U[300:], U[450:] = 1.0, 0.4, 0.8

# Structure 2 with n = 1 jumps at t = L, so between two samples only the sample
# after the jump sees L: its delay is defined to one sampling interval.  The
# other cases pin every parameter.
CASES = [
    StepModel(1, 1.5, 20.0, n=1, L=3.3),
    StepModel(1, 2.0, 12.0, n=2, L=0.0),
    StepModel(1, -0.8, 9.0, n=3, L=5.5),
    StepModel(1, 1.1, 6.0, n=4, L=1.7),
    StepModel(2, 1.2, 15.0, Tz=8.0, n=2, L=2.2),
    StepModel(2, 0.9, 10.0, Tz=-6.0, n=3, L=4.4),
    StepModel(3, 0.03, L=7.5),
    StepModel(4, 0.02, 10.0, L=3.7),
    StepModel(5, 0.02, 10.0, Tz=4.0, L=2.5),
]


def _record(model: StepModel, y0: float = 0.4, k0: float = 0.0) -> np.ndarray:
    return simulate_steps(model, H, N, find_steps(U), y0=y0, k0=k0)


def test_closed_forms_match_a_simulation_of_the_transfer_function() -> None:
    """Each closed form is the step response of its DelayTF (lsim of num/den, then
    the delay), so the formulas and tf() agree."""
    t = np.arange(0, 200.0, 0.05)
    for m in CASES:
        g = m.tf()
        _, y, _ = signal.lsim((g.num, g.den), np.ones_like(t), t)
        expected = np.interp(t - g.delay, t, y, left=0.0)
        assert np.allclose(m.step_response(t), expected, atol=1e-6 * max(1.0, abs(y).max())), m


def test_tf_coefficients() -> None:
    g = StepModel(2, 2.0, 3.0, Tz=5.0, n=2, L=1.0).tf()
    assert g.num == (10.0, 2.0) and g.den == (9.0, 6.0, 1.0) and g.delay == 1.0
    assert StepModel(3, 0.5, L=2.0).tf().integrators == 1
    assert StepModel(5, 0.5, 4.0, Tz=1.0).tf().den == (4.0, 1.0, 0.0)


def test_find_steps_gives_positions_and_sizes() -> None:
    steps = find_steps(U)
    assert steps.index.tolist() == [50, 300, 450]
    assert np.allclose(steps.size, [1.0, -0.6, 0.4])


def test_find_steps_ignores_small_changes_and_measures_ramps_to_the_level() -> None:
    u = np.full(100, 2.0)
    u[20:] += 0.01          # 1 % of the span: not a step
    u[40], u[41:] = 2.5, 3.01  # a two-sample ramp: one step, measured to the level
    steps = find_steps(u)
    assert steps.index.tolist() == [40]
    # From the level before the first step (2.0): the small change is folded in.
    assert steps.size[0] == pytest.approx(1.01)


def test_constant_input_is_refused() -> None:
    with pytest.raises(IdentificationError, match="constant"):
        find_steps(np.ones(50))


@pytest.mark.parametrize("model", CASES, ids=str)
def test_noiseless_parameters_recovered_to_1e_3(model: StepModel) -> None:
    k0 = 0.001 if model.structure >= 3 else 0.0
    fit = fit_step(U, _record(model, k0=k0), H, model.structure, model.n)
    got, want = fit.model.params(), model.params()
    for name, value in want.items():
        assert got[name] == pytest.approx(value, rel=1e-3, abs=1e-3 if value == 0 else 0), name
    assert fit.y0 == pytest.approx(0.4, rel=1e-6)
    assert fit.k0 == pytest.approx(k0, abs=1e-9)
    assert fit.loss < 1e-20


def test_order_is_chosen_when_not_given() -> None:
    model = StepModel(1, 2.0, 8.0, n=3, L=2.0)
    fit = fit_step(U, _record(model), H, 1)
    assert fit.model.n == 3
    assert fit.model.T == pytest.approx(8.0, rel=1e-3)


def test_with_noise_within_stated_tolerance() -> None:
    """White noise of 1 % of the largest step (sigma 0.01): K within 1 %, T within
    3 %, L within 0.5 s; the loss is at most the noise's own mean square (the true
    parameters give that) and not much below (5 parameters fitted to 600 points)."""
    rng = np.random.default_rng(7)
    for model in (StepModel(1, 1.5, 20.0, n=2, L=3.3), StepModel(4, 0.02, 10.0, L=3.7)):
        noise = rng.normal(0, 0.01, N)
        y = _record(model, k0=0.0005 if model.structure == 4 else 0.0) + noise
        fit = fit_step(U, y, H, model.structure, model.n)
        assert fit.model.K == pytest.approx(model.K, rel=0.01)
        assert fit.model.T == pytest.approx(model.T, rel=0.03)
        assert fit.model.L == pytest.approx(model.L, abs=0.5)
        assert 0.97 * np.mean(noise**2) < fit.loss <= np.mean(noise**2)


def test_manual_starting_values_are_used() -> None:
    model = StepModel(1, 1.5, 20.0, n=1, L=3.3)
    fit = fit_step(U, _record(model), H, 1, 1, start={"T": 18.0, "L": 3.0})
    assert fit.model.T == pytest.approx(20.0, rel=1e-3)


def test_a_prbs_is_a_sum_of_steps() -> None:
    """Piecewise-constant input: the superposition is the exact ZOH response."""
    rng = np.random.default_rng(3)
    u = np.repeat(rng.choice([-1.0, 1.0], 20), 30)
    model = StepModel(1, 2.5, 25.0, n=1, L=0.0)
    g = model.tf()
    sysd = signal.cont2discrete(signal.tf2ss(g.num, g.den), H, method="zoh")
    y = signal.dlsim(sysd, u - u[0])[1][:, 0] + 1.0
    fit = fit_step(u, y, H, 1, 1)
    assert fit.model.K == pytest.approx(2.5, rel=1e-4)
    assert fit.model.T == pytest.approx(25.0, rel=1e-4)


def test_bad_input() -> None:
    with pytest.raises(IdentificationError, match="too few rows"):
        fit_step(U[:5], U[:5], H)
    with pytest.raises(IdentificationError, match="structure"):
        fit_step(U, U, H, 6)
    with pytest.raises(IdentificationError, match="no step"):
        fit_step(np.r_[np.zeros(20), 1.0, np.zeros(20)] * 0 + np.linspace(0, 1, 41), U[:41], H)
