"""The MPC's prediction step (issue 26): the QP predicts on a grid k sampling times
apart with the input held over each step, the estimator and the solve still run
every sample.  The coarse model is the fine one k samples on, the unconstrained MPC
is the LQR of the coarse model, the rate limit allows one sample's change to the
first move, the preview reads the references k samples apart, and at P+ the longer
look-ahead this buys tracks a step the same-size QP at the loop's grid cannot."""

from __future__ import annotations

import copy
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from quadtank_tui.core.controllers.mpc.predictive import MPC, design_mpc
from quadtank_tui.core.controllers.mpc.model import plant_in_use
from quadtank_tui.core.controllers.mpc.settings import MPCSettings
from quadtank_tui.core.controllers.mpc.simulate import run_mpc, standard_scenario
from quadtank_tui.core.controllers.signals import Generator, Wave, WaveParams
from quadtank_tui.engine.mpc_control import future_references
from quadtank_tui.files.par import read_par

PARAMS = Path(__file__).resolve().parents[4] / "params"


def _design(name: str, tsamp_s: float, **settings):
    p = read_par(PARAMS / f"{name}.par").params.with_values({"SAMPLING TIME.TSamp": tsamp_s * 1000.0})
    plant, levels = plant_in_use(p)
    return plant, design_mpc(plant, levels, MPCSettings(**settings), p.tsamp)


def test_the_prediction_model_is_the_loop_model_k_samples_on() -> None:
    _, d = _design("nonminphase", 0.1, horizon=20, step=0.5)
    fine, coarse = d.model, d.prediction
    assert d.step_samples == 5 and coarse.T == pytest.approx(0.5) and fine.T == pytest.approx(0.1)
    Ak = np.linalg.matrix_power(fine.A, 5)
    Bk = sum(np.linalg.matrix_power(fine.A, i) @ fine.B for i in range(5))
    assert np.allclose(coarse.A, Ak, atol=1e-12) and np.allclose(coarse.B, Bk, atol=1e-12)
    assert np.allclose(coarse.Bd[:, :2], Bk, atol=1e-12)  # an input disturbance enters as the input
    # the same steady states: the disturbance estimate and the targets carry over
    dist = np.array([0.3, -0.2, 0.1, 0.05])
    for a, b in zip(fine.target(dist, np.array([1.0, -0.5])), coarse.target(dist, np.array([1.0, -0.5]))):
        assert np.allclose(a, b, atol=1e-9)
    # a step of 0 (or shorter than half a sample) is the sampling time: one model
    for step in (0.0, 0.04):
        same = _design("nonminphase", 0.1, horizon=20, step=step)[1]
        assert same.prediction is same.model and same.step_samples == 1


def test_the_unconstrained_mpc_is_the_lqr_of_the_coarse_model() -> None:
    from scipy.linalg import solve_discrete_are

    _, d = _design("nonminphase", 0.1, horizon=60, step=1.0)
    c = MPC(d)
    mdl, w = d.prediction, d.weights
    P = solve_discrete_are(mdl.A, mdl.B, w.Q, w.R)
    K = np.linalg.solve(w.R + mdl.B.T @ P @ mdl.B, mdl.B.T @ P @ mdl.A)
    assert np.abs(c.qp.unconstrained_gain()[:, : mdl.n] - K).max() < 1e-6


def test_the_rate_limit_allows_one_sample_of_change_to_the_first_move() -> None:
    _, d = _design("minphase", 0.1, horizon=20, step=1.0, rate_limit=0.5)
    c = MPC(d)
    mdl = d.model
    c.track(mdl.x_e, mdl.u_e)
    u = [c.step(mdl.x_e[list(mdl.measured)] - 2.0, mdl.x_e[:2] + 2.0).u for _ in range(3)]
    moves = np.abs(np.diff(np.vstack([mdl.u_e, *u]), axis=0))
    assert moves.max() == pytest.approx(0.5 * 0.1, rel=1e-6)  # V/s x the loop's 0.1 s, not x 1 s


@pytest.mark.parametrize("wave, ramp", [(Wave.SQUARE, False), (Wave.SINE, True), (Wave.PRBS, False), (Wave.PRBS, True)])
def test_the_preview_on_the_coarse_grid_is_every_kth_sample(wave: Wave, ramp: bool) -> None:
    g = Generator(WaveParams(wave, 0.3, 0.05, 7.0 if wave is Wave.PRBS else 6.0, True, seed=5), 0.1)
    g.take(13)
    if ramp:
        g.nudge(0.2)  # the mean ramps towards 0.5 over the horizon
    before = copy.deepcopy(g)
    other = Generator(WaveParams(Wave.SQUARE, 0.4, 0.0, 60.0, False), 0.1)
    fine = future_references([g, other], 60 * 4)
    coarse = future_references([g, other], 60, every=4)
    assert coarse.shape == (61, 2)
    assert np.allclose(coarse, fine[::4], atol=1e-12)
    assert g.take(300) == before.take(300)  # the loop's own generator did not move
    if ramp:
        assert coarse[-1, 0] - coarse[0, 0] > 0.1  # the ramp is in the preview


def test_at_p_plus_a_coarse_grid_sees_past_the_inverse_response() -> None:
    """P+ at T = 1 s, the standard steps (announced): N = 20 looks 20 s ahead, a third
    of the inverse response; on a 3-s grid the same QP sees 60 s (and tracks within
    3 % of N = 60 on the loop's grid, three times the variables: measured, not
    asserted, to keep the test short)."""
    iae = {}
    for N, step in ((20, 0.0), (20, 3.0)):
        plant, d = _design("nonminphase", 1.0, horizon=N, step=step)
        x_e = d.model.x_e
        scn = standard_scenario(plant, x_e, phase=400.0, lead=80.0)
        assert scn.leak is not None
        scn = replace(scn, leak=None, duration=scn.leak[0])
        run = run_mpc(plant, MPC(d), x_e, scn)
        iae[N, step] = np.sum(np.abs(run.r - run.x[:, :2]), axis=0)
        assert run.u.min() >= 0.0 and run.u.max() <= 10.0 and run.faults == 0
    assert np.all(iae[20, 3.0] < 0.75 * iae[20, 0.0]), iae  # measured 0.67, 0.55
