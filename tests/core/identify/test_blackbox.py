"""Output-error, ARX and subspace fits against models with a known answer: the
physical linearization at P- and P+, simulated exactly (ZOH), with and without
measurement noise."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from quadtank_tui.core.analysis import analyze
from quadtank_tui.core.identify import IdentificationError
from quadtank_tui.core.identify.arx import fit_arx
from quadtank_tui.core.identify.oe import OEModel, fit_oe
from quadtank_tui.core.identify.sampling import d2c, simulate
from quadtank_tui.core.identify.step import StepModel, find_steps, simulate_steps
from quadtank_tui.core.identify.subspace import fit_subspace
from quadtank_tui.core.identify.system import from_elements, from_state_space
from quadtank_tui.core.plants.johansson import P_MINUS, P_PLUS, steady_state_levels

H = 1.0


def prbs(n: int, hold: int, seed: int) -> np.ndarray:
    """A random binary signal held `hold` samples, starting with one row of rest (0)."""
    rng = np.random.default_rng(seed)
    levels = rng.choice([-1.0, 1.0], n // hold + 1)
    return np.r_[0.0, np.repeat(levels, hold)[: n - 1]]


def physical(setting):
    return analyze(setting.params, steady_state_levels(setting.op.u, setting.params))


def element_tf(a, o: int, i: int) -> tuple[np.ndarray, np.ndarray]:
    e = a.G[o][i]
    den = np.array([1.0])
    for T in e.lags:
        den = np.polymul(den, [T, 1.0])
    return np.array([e.gain]), den


def test_zoh_simulation_equals_the_superposed_closed_forms() -> None:
    """Two independent routes to the sampled response of a delayed model: the ZOH
    filter with a fractional delay and Andersson's closed forms, summed over steps."""
    u = np.zeros(300)
    u[10:], u[100:], u[200:] = 1.0, -0.5, 0.3
    for m in (StepModel(1, 1.5, 20.0, n=1, L=3.3), StepModel(1, 2.0, 12.0, n=3),
              StepModel(2, 0.9, 10.0, Tz=-6.0, n=3, L=4.4), StepModel(2, 1.2, 15.0, Tz=8.0, n=1, L=2.2),
              StepModel(4, 0.02, 10.0, L=3.7)):
        g = m.tf()
        zoh = simulate(np.array(g.num), np.array(g.den), H, u, g.delay)
        closed = simulate_steps(m, H, u.size, find_steps(u))
        assert np.abs(zoh - closed).max() < 1e-10, m


@pytest.mark.parametrize("o,i", [(0, 0), (0, 1), (1, 0), (1, 1)])
def test_oe_recovers_the_linearization_exactly_without_noise(o: int, i: int) -> None:
    a = physical(P_PLUS)
    num, den = element_tf(a, o, i)
    u = 0.03 * prbs(3600, 60, seed=1)
    y = 0.62 + simulate(num, den, H, u)
    fit = fit_oe(u + 0.315, y, H, order=1 if o == i else 2, u0=0.315)
    assert fit.model.K == pytest.approx(a.G[o][i].gain, rel=1e-4)
    assert sorted(fit.model.T) == pytest.approx(sorted(a.G[o][i].lags), rel=1e-3)
    assert fit.model.L == pytest.approx(0.0, abs=1e-3)
    assert fit.offset == pytest.approx(0.62, abs=1e-9)


def test_oe_with_a_zero_and_a_delay() -> None:
    true = OEModel((-0.9 * 6.0, 0.9), (10.0, 25.0), 4.4)  # K (1 - 6 s) / ((1 + 10 s)(1 + 25 s)) e^-4.4s
    u = prbs(2000, 40, seed=5)
    y = simulate(np.array(true.num), np.array(true.den), H, u, true.L)
    fit = fit_oe(u, y, H, order=2, zeros=1)
    assert fit.model.K == pytest.approx(0.9, rel=1e-3)
    assert fit.model.Tz == pytest.approx((-6.0,), rel=1e-3)
    assert fit.model.T == pytest.approx((10.0, 25.0), rel=1e-3)
    assert fit.model.L == pytest.approx(4.4, abs=1e-2)


def test_arx_is_biased_by_noise_and_oe_is_not() -> None:
    """control.md: on noisy SIMO data the equation-error ARX gain of the path through
    an upper tank comes out far off, the output-error fit within 3 %."""
    a = physical(P_MINUS)
    num, den = element_tf(a, 1, 0)  # G21 = 1.41 / ((1 + 30 s)(1 + 91 s))
    u = 0.015 * prbs(3600, 60, seed=2)
    rng = np.random.default_rng(4)
    y = simulate(num, den, H, u) + rng.normal(0.0, 0.002, u.size)  # 0.02 V of sensor noise
    gain = a.G[1][0].gain
    oe = fit_oe(u, y, H, order=2, delay=False)
    arx = fit_arx(u, y, H, 2, 2, 1)
    assert oe.model.K == pytest.approx(gain, rel=0.03)
    assert abs(arx.static_gain / gain - 1) > 0.3


def test_arx_without_noise_is_exact() -> None:
    a = physical(P_MINUS)
    num, den = element_tf(a, 0, 0)
    u = prbs(1000, 30, seed=3)
    fit = fit_arx(u, simulate(num, den, H, u), H, 1, 1, 1)
    assert fit.static_gain == pytest.approx(a.G[0][0].gain, rel=1e-9)
    assert fit.tf is not None
    assert fit.tf.static_gain == pytest.approx(a.G[0][0].gain, rel=1e-6)
    assert fit.tf.den[0] / fit.tf.den[-1] == pytest.approx(a.G[0][0].lags[0], rel=1e-6)


def test_d2c_inverts_zoh_sampling() -> None:
    A = np.array([[-0.05, 0.02], [0.0, -0.1]])
    B = np.array([[0.1, 0.0], [0.3, 0.2]])
    Ad, Bd, *_ = signal.cont2discrete((A, B, np.eye(2), np.zeros((2, 2))), 2.0, method="zoh")
    Ac, Bc = d2c(Ad, Bd, 2.0)
    assert np.allclose(Ac, A, atol=1e-12) and np.allclose(Bc, B, atol=1e-12)


@pytest.mark.parametrize("setting", [P_MINUS, P_PLUS], ids=["P-", "P+"])
def test_subspace_recovers_gains_and_zeros_of_the_2x2_process(setting) -> None:
    a = physical(setting)
    m = a.model
    sysd = signal.cont2discrete((m.A, m.B, m.C, m.D), H, method="zoh")
    u = np.column_stack([prbs(3600, 60, 11), prbs(3600, 60, 12)]) * 0.3
    _, y, _ = signal.dlsim(sysd[:4] + (H,), u)
    fit = fit_subspace(u, y, H, order=4)
    model = from_state_space(fit.A, fit.B, fit.C)
    assert model.static_gains == pytest.approx(a.static_gains, rel=1e-4)
    assert np.array(model.zeros) == pytest.approx(np.array(a.zeros), rel=1e-3)
    assert model.phase == a.phase
    assert sorted(-1 / np.linalg.eigvals(fit.A).real) == pytest.approx(sorted(a.time_constants), rel=1e-3)


def test_elements_fitted_apart_give_the_processes_zeros() -> None:
    """The lower tank's pole, identified in two elements of its output with slightly
    different values, is one pole: det G then has just the process's two zeros."""
    for setting in (P_MINUS, P_PLUS):
        a = physical(setting)
        from quadtank_tui.core.delaytf import DelayTF

        rows = []
        for o in range(2):
            row = []
            for i in range(2):
                num, den = element_tf(a, o, i)
                lags = [T * (1.004 if k == len(a.G[o][i].lags) - 1 and o != i else 1.0)
                        for k, T in enumerate(a.G[o][i].lags)]
                den = np.array([1.0])
                for T in lags:
                    den = np.polymul(den, [T, 1.0])
                row.append(DelayTF(tuple(num), tuple(den)))
            rows.append(row)
        model = from_elements(rows)
        assert len(model.zeros) == 2
        assert np.array(model.zeros) == pytest.approx(np.array(a.zeros), rel=0.02)
        assert model.phase == a.phase


def test_bad_data_refused() -> None:
    with pytest.raises(IdentificationError, match="constant"):
        fit_oe(np.ones(500), np.ones(500), H)
    with pytest.raises(IdentificationError, match="too few rows"):
        fit_oe(np.arange(20.0), np.arange(20.0), H, order=2)
    with pytest.raises(IdentificationError, match="every input"):
        fit_subspace(np.column_stack([prbs(2000, 20, 1), np.zeros(2000)]), np.zeros((2000, 2)), H)
