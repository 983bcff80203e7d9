"""The laminar outflow term, the sensor offsets and the cascade's upper tank of
another cross-section (issue 40): each against its equation written out here, the
steady states and linearizations consistent with the right-hand side, and the
`.par` carrying them."""

from __future__ import annotations

import math
from datetime import datetime

import numpy as np
import pytest

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.core.plants import CoupledCascade, DesautelQTP, QuadTank
from quadtank_tui.core.plants.johansson import P_MINUS
from quadtank_tui.files.par import format_par, parse_par

G = 981.0
LAM = dict(lam1=0.1, lam2=0.08, lam3=0.09, lam4=0.07)


def test_quadruple_tank_laminar_outlets_and_offsets_as_written() -> None:
    p = P_MINUS.params
    rig = QuadTank(p, **LAM, off1=0.06, off2=-0.04)
    h, v = (12.0, 13.0, 2.0, 1.5), (3.0, 3.5)
    q = [a * math.sqrt(2 * G * x) + lam * x for a, x, lam in zip((p.a1, p.a2, p.a3, p.a4), h, LAM.values())]
    want = ((-q[0] + q[2] + p.gamma1 * p.k1 * v[0]) / p.A1, (-q[1] + q[3] + p.gamma2 * p.k2 * v[1]) / p.A2,
            (-q[2] + (1 - p.gamma2) * p.k2 * v[1]) / p.A3, (-q[3] + (1 - p.gamma1) * p.k1 * v[0]) / p.A4)
    assert rig.rhs(h, v) == pytest.approx(want, rel=1e-12)
    assert rig.output(h) == pytest.approx((p.kc * 12 + 0.06, p.kc * 13 - 0.04, p.kc * 2, p.kc * 1.5), rel=1e-12)


@pytest.mark.parametrize("rig", [QuadTank(P_MINUS.params, **LAM), DesautelQTP(lam1=0.01, lam3=0.004)])
def test_laminar_steady_states_linearization_and_operating_point(rig) -> None:
    x = rig.steady_state((3.0, 3.0))
    assert max(abs(r) for r in rig.rhs(x, (3.0, 3.0))) < 1e-10
    op = rig.steady_inputs((x[0], x[1]))
    assert op.u == pytest.approx((3.0, 3.0), rel=1e-9) and op.x == pytest.approx(x, rel=1e-9)
    A, B, _ = rig.jacobians(x, (3.0, 3.0))
    eps = 1e-6
    for j in range(4):
        up = list(x)
        up[j] += eps
        col = (np.array(rig.rhs(up, (3.0, 3.0))) - np.array(rig.rhs(x, (3.0, 3.0)))) / eps
        assert np.array(A)[:, j] == pytest.approx(col, rel=1e-4, abs=1e-9)
    # without the laminar terms the linearization is slower: the laminar slope adds to each pole
    plain = rig.with_values(lam1=0.0, lam2=0.0, lam3=0.0, lam4=0.0)
    assert np.all(np.diag(np.array(A)) < np.diag(np.array(plain.jacobians(x, (3.0, 3.0))[0])) + 1e-15)


def test_cascade_laminar_offsets_and_a_wider_upper_tank() -> None:
    rig = CoupledCascade(lam1=0.004, lam2=0.003, area1=2.5, off2=0.2)
    x, u = (12.0, 9.0), (6.0,)
    q1 = rig.alpha1 * math.sqrt(2 * G * 12) + 0.004 * 12
    q2 = rig.alpha2 * math.sqrt(2 * G * 9) + 0.003 * 9
    assert rig.rhs(x, u) == pytest.approx(((rig.beta1 * 6 - q1) / 2.5, q1 - q2), rel=1e-12)
    assert rig.output(x) == pytest.approx((rig.kc1 * 12, rig.kc2 * 9 + 0.2), rel=1e-12)
    s = rig.steady_state(u)
    assert max(abs(r) for r in rig.rhs(s, u)) < 1e-12
    op = rig.steady_inputs((s[0], None))
    assert op.u == pytest.approx(u, rel=1e-9)
    A, B, _ = rig.jacobians(s, u)
    col = (np.array(rig.rhs((s[0] + 1e-6, s[1]), u)) - np.array(rig.rhs(s, u))) / 1e-6
    assert np.array(A)[:, 0] == pytest.approx(col, rel=1e-4)
    assert B == [[pytest.approx(rig.beta1 / 2.5)], [0.0]]
    # an upper tank at its brim spills in the fitted fraction, at its own height
    full = CoupledCascade(lam1=0.004, lam2=0.003, area1=2.5, off2=0.2, spill1=0.5)
    f = full.rhs((30.0, 9.0), (20.0,))
    excess = full.beta1 * 20 - (full.alpha1 * math.sqrt(2 * G * 30) + 0.004 * 30)
    assert f == pytest.approx((0.0, full.alpha1 * math.sqrt(2 * G * 30) + 0.004 * 30 - q2 + 0.5 * excess))


def test_the_par_carries_them_and_off_they_are_not_written() -> None:
    import dataclasses

    from quadtank_tui.core.plants.spec import PlantSpec

    stamp = datetime(2026, 1, 1)
    plain = format_par(PRESET, stamp)
    assert "lam1" not in plain and "off1" not in plain
    rig = CoupledCascade(lam1=0.004, area1=2.5, off2=0.2)
    params = dataclasses.replace(PRESET, process=PlantSpec.of(rig, rig.steady_state((8.0,))))
    text = format_par(params, stamp)
    assert "lam1 0.004" in text and "area1 2.5" in text and "off2 0.2" in text and "lam2" not in text
    back = parse_par(text, name="t.par").params.process_plant()
    assert back == rig
