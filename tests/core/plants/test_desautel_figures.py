"""Desautel's published CTP and QTP figures from the plants' own linearizations
(001_..., 2.1.13-2.1.14, the CTP simulation block of chapter 3, 4.1.6-4.1.7, 4.2)."""

from __future__ import annotations

import numpy as np
import pytest

from quadtank_tui.core.plants import CoupledCascade, DesautelQTP


def ctp_at_15cm():
    p = CoupledCascade()
    op = p.steady_inputs((15.0, None))
    return p, op, p.control_model(op.x, op.u)


def test_ctp_lambdas_at_x1_15cm() -> None:
    _, _, m = ctp_at_15cm()
    assert -m.A[0, 0] == pytest.approx(0.055988, abs=5e-7)  # lambda1
    assert -m.A[1, 1] == pytest.approx(0.057025, abs=5e-7)  # lambda2
    assert m.A[1, 0] == -m.A[0, 0] and m.A[0, 1] == 0.0
    assert m.B[:, 0].tolist() == [0.24813, 0.0]


def test_ctp_equilibrium() -> None:
    """(2.1.5), (2.1.6): u_e = alpha1 sqrt(2 g 15) / beta1, x2 = alpha1^2 15 / alpha2^2."""
    _, op, _ = ctp_at_15cm()
    assert op.x[1] == pytest.approx(0.0097909**2 * 15 / 0.0098811**2, rel=1e-12)
    assert op.u[0] == pytest.approx(0.0097909 * np.sqrt(2 * 981 * 15) / 0.24813, rel=1e-12)


def test_ctp_zoh_matrices_at_100ms() -> None:
    _, _, m = ctp_at_15cm()
    phi, gamma = m.c2d(0.1)
    np.testing.assert_allclose(phi, [[0.99442, 0.0], [0.0055673, 0.99431]], atol=5e-6, rtol=0)
    assert gamma[0, 0] == pytest.approx(0.024744, abs=5e-7)
    assert gamma[1, 0] == pytest.approx(0.000069201, abs=5e-10)


def test_qtp_poles_and_zeros_at_6_volts() -> None:
    p = DesautelQTP()
    x = p.steady_state((6.0, 6.0))
    m = p.control_model(x, (6.0, 6.0))
    # (4.1.6) prints -0.05201, his A matrix in 4.2 prints 0.05202: ours is -0.052015
    assert sorted(m.poles().real) == pytest.approx(sorted([-0.06758, -0.07438, -0.03308, -0.052015]), abs=6e-6)
    assert m.zeros().real == pytest.approx([-0.06090, -0.02419], abs=5e-6)
    assert np.all(m.zeros().imag == 0)


def test_qtp_matrices_of_section_4_2() -> None:
    p = DesautelQTP()
    x = p.steady_state((6.0, 6.0))
    m = p.control_model(x, (6.0, 6.0))
    lam = -np.diag(m.A)
    assert m.A[0, 2] == pytest.approx(lam[2], rel=1e-12) and m.A[1, 3] == pytest.approx(lam[3], rel=1e-12)
    np.testing.assert_allclose(m.B, [[0.21009, 0], [0, 0.23525], [0, 0.079938], [0.088820, 0]], rtol=1e-12)
    phi, gamma = m.c2d(0.1)
    np.testing.assert_allclose(np.diag(phi), [0.9933, 0.9926, 0.9967, 0.9948], atol=5e-5)
    assert phi[0, 2] == pytest.approx(0.003291, abs=5e-7) and phi[1, 3] == pytest.approx(0.005169, abs=5e-7)
    np.testing.assert_allclose(gamma, [[0.02094, 0.00001318], [0.00002300, 0.02344], [0, 0.007981],
                                       [0.008859, 0]], atol=5e-6, rtol=0)
    assert gamma[0, 1] == pytest.approx(0.00001318, abs=5e-9)
