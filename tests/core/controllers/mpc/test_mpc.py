"""The MPC core (issue 26): the unconstrained MPC is the LQR, limits hold on the
nonlinear plant, a leak leaves no offset, a failed solve holds the input."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from quadtank_tui.core.controllers.matrix import ELEMENTS, ControllerMatrix
from quadtank_tui.core.controllers.mpc.predictive import MPC, MPCStats, design_mpc, percentiles
from quadtank_tui.core.controllers.mpc.model import plant_in_use
from quadtank_tui.core.controllers.mpc.settings import MPCSettings
from quadtank_tui.core.controllers.mpc.simulate import Scenario, figures, run_mpc, run_pi, standard_scenario
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.files.par import read_par

PARAMS = Path(__file__).resolve().parents[4] / "params"
FILES = ("minphase", "nonminphase", "desautel-qtp", "coupled-cascade", "coupled-tito")


def _params(name: str, tsamp_s: float):
    return read_par(PARAMS / f"{name}.par").params.with_values({"SAMPLING TIME.TSamp": tsamp_s * 1000.0})


def _mpc(name: str, tsamp_s: float = 2.0, **settings) -> tuple:
    p = _params(name, tsamp_s)
    plant, levels = plant_in_use(p)
    return p, plant, MPC(design_mpc(plant, levels, MPCSettings(**settings), p.tsamp))


def _lqr(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, S: np.ndarray) -> np.ndarray:
    """The discrete LQR on [x; u_prev] with stage cost x'Qx + u'Ru + du'S du, from
    scipy's Riccati solver (written out here, independent of core.controllers.mpc.qp)."""
    n, m = B.shape
    Aa = np.block([[A, np.zeros((n, m))], [np.zeros((m, n + m))]])
    Ba = np.vstack([B, np.eye(m)])
    Qa = np.block([[Q, np.zeros((n, m))], [np.zeros((m, n)), S]])
    Na = np.vstack([np.zeros((n, m)), -S])
    P = solve_discrete_are(Aa, Ba, Qa, R + S, s=Na)
    return np.linalg.solve(R + S + Ba.T @ P @ Ba, Ba.T @ P @ Aa + Na.T)


@pytest.mark.parametrize("name, rate", [(f, 0.0) for f in FILES] + [("minphase", 0.5), ("nonminphase", 0.5)])
def test_unconstrained_mpc_is_the_discrete_lqr(name: str, rate: float) -> None:
    _, _, c = _mpc(name, 1.0, horizon=60, rate_weight=rate)
    mdl, w = c.design.model, c.design.weights
    # the weights as documented: relative to the tank heights and pump ranges
    qz = 1.0 / mdl.y_scale[list(mdl.tracked)] ** 2
    Q = mdl.Cz.T @ np.diag(qz) @ mdl.Cz
    R = np.diag(0.01 / mdl.u_scale ** 2)
    S = np.diag(rate / mdl.u_scale ** 2)
    assert np.allclose(w.Q, Q) and np.allclose(w.R, R) and np.allclose(w.S, S)
    K = _lqr(mdl.A, mdl.B, Q, R, S)
    assert np.abs(c.qp.unconstrained_gain() - K).max() < 1e-6
    # and OSQP's solution of the sample's QP, limits inactive, is the LQR's first move
    # levels below the point, the reference above it: every pump moves up (the two-input
    # rig's pump 2 runs at 0 V at its point, where a move down would meet its limit)
    x0 = -0.02 * mdl.y_scale * np.linspace(1.0, 0.5, mdl.n)
    u_prev = 0.01 * mdl.u_scale
    r = 0.01 * mdl.y_scale[list(mdl.tracked)]
    d = np.zeros(mdl.nd)
    xs, us = mdl.target(d, np.tile(r, (c.qp.N + 1, 1)))
    v, status = c.qp.solve(*c.qp.vectors(x0, d, xs, us, u_prev))
    assert v is not None, status
    expected = us[0] - K @ np.concatenate([x0 - xs[0], u_prev - us[0]])
    assert np.all(expected + mdl.u_e > mdl.u_lo) and np.all(expected + mdl.u_e < mdl.u_hi)
    assert np.abs(v[c.qp.ui(0)] - expected).max() < 1e-6 * mdl.u_scale.max()


def test_targets_put_the_tracked_levels_on_the_reference_with_a_disturbance() -> None:
    _, _, c = _mpc("minphase", 1.0)
    mdl = c.design.model
    d = np.array([0.3, -0.2, 0.1, 0.05])  # two pump errors (V), two level offsets (cm)
    xs, us = mdl.target(d, np.array([1.0, -0.5]))
    assert np.allclose(mdl.A @ xs + mdl.B @ us + mdl.Bd @ d, xs)
    assert np.allclose(mdl.Cz @ xs + mdl.Czd @ d, [1.0, -0.5])


def _pi(p) -> ControllerMatrix:
    return ControllerMatrix(p.tsamp, p.control.family, p.control.structure,
                            pid={e: c.pid for e, c in zip(ELEMENTS, p.controllers)})


@pytest.mark.parametrize("name, phase", [("minphase", 200.0), ("nonminphase", 400.0)])
def test_large_steps_keep_pumps_and_levels_within_limits(name: str, phase: float) -> None:
    p, plant, c = _mpc(name, 2.0, horizon=30)
    mdl = c.design.model
    scn = standard_scenario(plant, mdl.x_e, phase=phase, lead=70.0)
    assert scn.leak is not None
    scn = replace(scn, leak=None, duration=scn.leak[0])  # the steps only: the leak is tested below
    run = run_mpc(plant, c, mdl.x_e, scn)
    pi = run_pi(plant, _pi(p), mdl.x_e, mdl.u_e, scn)
    f_mpc = figures(plant, run, scn, mdl.x_lo, mdl.x_hi)
    f_pi = figures(plant, pi, scn, mdl.x_lo, mdl.x_hi)
    assert run.u.min() >= 0.0 and run.u.max() <= 10.0  # as commanded, before the plant
    assert np.all(run.x >= 0.0) and np.all(run.x <= mdl.x_hi + 0.05)  # soft: within 0.5 mm
    assert run.faults == 0
    # the steps are demanding: the PI saturates a pump (P-) or overflows a tank (P+)
    assert f_pi.at_limit > 0 or f_pi.violations > 0
    assert f_mpc.at_limit > 0  # and the MPC uses the pumps' range
    for loop in range(2):  # and the MPC tracks: the final levels on the references
        assert run.x[-1, loop] == pytest.approx(run.r[-1, loop], abs=0.1)


@pytest.mark.parametrize("name, disturbance, measured", [
    ("minphase", "input", "all"), ("minphase", "output", "all"), ("minphase", "input", "1 2"),
    ("nonminphase", "input", "all")])
def test_a_constant_leak_on_tank_1_leaves_no_offset(name: str, disturbance: str, measured: str) -> None:
    _, plant, c = _mpc(name, 4.0, horizon=20, disturbance=disturbance, measured=measured)
    mdl = c.design.model
    r0 = tuple(mdl.x_e[:2])
    area = 0.15 * plant.values()["a1"]
    scn = Scenario(r0, (), (0.0, 1, area), 1000.0 if name == "minphase" else 2400.0)
    run = run_mpc(plant, c, mdl.x_e, scn)
    assert np.abs(run.x[-1, :2] - np.array(r0)).max() < 2e-3  # cm
    # and the leak really acted: the pumps settled away from the operating point
    assert np.abs(run.u[-1] - mdl.u_e).max() > 0.05


def _warm(c: MPC) -> np.ndarray:
    mdl = c.design.model
    c.track(mdl.x_e, mdl.u_e + 0.5)
    return c.step(mdl.x_e[list(mdl.measured)] + 0.2, mdl.x_e[:2]).u


def test_a_failed_solve_holds_the_last_input_and_counts() -> None:
    _, _, c = _mpc("minphase", 1.0, horizon=20)
    mdl = c.design.model
    u1 = _warm(c)
    c.qp._solver.update_settings(max_iter=1)  # OSQP stops before it converges
    out = c.step(mdl.x_e + 0.3, mdl.x_e[:2])
    assert out.fault and c.stats.faults == 1 and np.array_equal(out.u, u1)
    assert "max" in c.stats.last_status.lower()
    c.qp._solver.update_settings(max_iter=4000)  # the settings in force
    assert not c.step(mdl.x_e + 0.3, mdl.x_e[:2]).fault


def test_a_raising_solver_or_a_bad_reading_never_raises() -> None:
    _, _, c = _mpc("minphase", 1.0, horizon=20)
    mdl = c.design.model
    u1 = _warm(c)

    def boom(*args):
        raise RuntimeError("solver crashed")

    c.qp.solve = boom
    out = c.step(mdl.x_e, mdl.x_e[:2])
    assert out.fault and np.array_equal(out.u, u1) and "solver crashed" in c.stats.last_status
    del c.qp.solve
    out = c.step([np.nan, 12.0, 2.0, 2.0], mdl.x_e[:2])
    assert out.fault and np.array_equal(out.u, u1) and c.stats.faults == 2
    assert len(c.stats.times) == len(c.stats.cpu_times) == 3


def test_a_held_input_respects_the_rate_limit_and_the_range() -> None:
    _, _, c = _mpc("minphase", 1.0, horizon=20, rate_limit=0.5)
    mdl = c.design.model
    c.track(mdl.x_e, np.array([10.0, 0.0]))
    steps = [c.step(mdl.x_e - 3.0, mdl.x_e[:2] + 3.0).u for _ in range(5)]
    moves = np.abs(np.diff(np.vstack([[10.0, 0.0]] + steps), axis=0))
    assert moves.max() <= 0.5 * 1.0 + 1e-9
    assert np.all(np.vstack(steps) >= 0.0) and np.all(np.vstack(steps) <= 10.0)


@pytest.mark.parametrize("name", FILES)
def test_every_shipped_plant_designs(name: str) -> None:
    _, plant, c = _mpc(name, 0.1, horizon=30)
    mdl = c.design.model
    assert mdl.n == len(plant.states) and mdl.m == len(plant.inputs)
    assert np.all(np.abs(c.design.closed_loop_poles()) < 1.0)
    assert bool(mdl.note) == (name == "coupled-tito")  # its file's levels need pump 2 reversed


@pytest.mark.parametrize("changes, key", [
    (dict(horizon=0), "Horizon"), (dict(horizon=10, control_horizon=11), "ControlHorizon"),
    (dict(input_weight=0.0), "InputWeight"), (dict(disturbance="state"), "Disturbance"),
    (dict(measured="1 x"), "Measured"), (dict(preview=2), "Preview")])
def test_bad_settings_name_the_key(changes: dict, key: str) -> None:
    with pytest.raises(ParameterError) as err:
        MPCSettings(**changes)
    assert err.value.field == key


def test_an_untracked_measurement_set_is_refused() -> None:
    p = _params("minphase", 1.0)
    plant, levels = plant_in_use(p)
    with pytest.raises(ParameterError, match="tracked tank"):
        design_mpc(plant, levels, MPCSettings(measured="1 3"), p.tsamp)
    with pytest.raises(ParameterError, match="has 2 tanks"):
        pc = _params("coupled-cascade", 1.0)
        design_mpc(*plant_in_use(pc), MPCSettings(measured="1 2 3"), pc.tsamp)


def test_solve_time_percentiles_interpolate_and_are_nan_without_solves() -> None:
    """One function for the statistics, the figures and the controller box: linear
    interpolation between the ordered times (NumPy's default), NaN when none."""
    times = [0.004, 0.001, 0.003, 0.002]
    assert percentiles(times, (50, 99)) == pytest.approx((0.0025, 0.00397))
    assert percentiles(iter(times), (0, 100)) == (0.001, 0.004)
    assert all(np.isnan(p) for p in percentiles([], (50, 99)))
    assert MPCStats(times=times).percentile(50) == pytest.approx(0.0025)
    assert np.isnan(MPCStats().percentile(99))
