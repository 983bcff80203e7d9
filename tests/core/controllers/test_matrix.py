"""The 2x2 controller matrix: structure, anti-windup on the diagonal, type switches."""

from __future__ import annotations

import numpy as np
import pytest

from quadtank_tui.core.controllers.general import GeneralParams
from quadtank_tui.core.controllers.matrix import ControllerMatrix, Family, Structure, saturate
from quadtank_tui.core.controllers.pid import PIDParams
from quadtank_tui.core.ranges import ParameterError

P = PIDParams(K=0.0, integral=False)  # a silent element


def gain(k: float) -> PIDParams:
    return PIDParams(K=k, integral=False)


def test_enum_spellings_match_the_par_file() -> None:
    assert [f.value for f in Family] == ["PID", "General", "State feedback", "MPC"]
    assert [s.value for s in Structure] == ["Decentralized", "FullMatrix"]
    assert Family("General") is Family.GENERAL
    with pytest.raises(ParameterError, match="not a matrix family"):
        ControllerMatrix(1.0, Family.STATE_FEEDBACK)
    with pytest.raises(ParameterError, match="not a matrix family"):
        ControllerMatrix(1.0, Family.MPC)


def test_saturate_clips_to_the_pump_range() -> None:
    assert saturate((-0.2, 1.7)) == (0.0, 1.0)
    assert saturate((0.25, 0.75)) == (0.25, 0.75)


def test_element_ij_maps_error_j_to_input_i() -> None:
    pid = {(1, 1): gain(1.0), (1, 2): gain(10.0), (2, 1): gain(100.0), (2, 2): gain(1000.0)}
    m = ControllerMatrix(1.0, Family.PID, Structure.FULL_MATRIX, pid=pid)
    e = (0.01, 0.001)
    assert m.compute(e, (0.0, 0.0)) == pytest.approx((1.0 * 0.01 + 10.0 * 0.001, 100.0 * 0.01 + 1000.0 * 0.001))
    m.set_type(Family.PID, Structure.DECENTRALIZED)
    assert m.compute(e, (0.0, 0.0)) == pytest.approx((0.01, 1.0))


def test_general_family_uses_the_errors_too() -> None:
    general = {e: GeneralParams(degree=0, s=(k, 0, 0, 0, 0))
               for e, k in (((1, 1), 1.0), ((1, 2), 2.0), ((2, 1), 3.0), ((2, 2), 4.0))}
    m = ControllerMatrix(1.0, Family.GENERAL, Structure.FULL_MATRIX, general=general)
    assert m.compute((0.5, 0.5), (0.4, 0.3)) == pytest.approx((0.1 + 0.4, 0.3 + 0.8))


def test_anti_windup_only_on_the_diagonal() -> None:
    pi = PIDParams(K=1.0, Ti=10.0, Tr=1.0, b=0.0)
    m = ControllerMatrix(1.0, Family.PID, Structure.FULL_MATRIX, pid={e: pi for e in
                                                                      ((1, 1), (1, 2), (2, 1), (2, 2))})
    r, y = (1.0, 1.0), (0.0, 0.0)  # huge errors: both inputs saturate at 1
    for _ in range(20):
        v = m.compute(r, y)
        m.update(r, y, saturate(v))
    out = m.element_outputs((0.0, 0.0), (0.0, 0.0))  # the integral states alone
    # Off-diagonal elements integrate freely: 20 samples * K h/Ti * e = 2.0.
    assert out[(1, 2)] == pytest.approx(2.0) and out[(2, 1)] == pytest.approx(2.0)
    # The diagonal ones are pulled back by the whole excess of their input: with
    # h = Tr the tracking is deadbeat, I11(k+1) = I11 + 0.1 + (1 - I11 - I12(k)) with
    # I12(k) = 0.1 k, so I11 = 1.1 - 0.1 * 19 after the 20th sample and u1 stays 0.2
    # (one integration step of each element) above its limit.
    assert out[(1, 1)] == pytest.approx(-0.8) and out[(2, 2)] == pytest.approx(-0.8)
    assert out[(1, 1)] + out[(1, 2)] == pytest.approx(1.2)


def run(m: ControllerMatrix, n: int, r=(0.5, 0.5), y=(0.4, 0.45)) -> None:
    for _ in range(n):
        m.update(r, y, saturate(m.compute(r, y)))


def test_structure_switch_keeps_states_family_switch_resets() -> None:
    pi = {(1, 1): PIDParams(K=1.0, Ti=5.0), (2, 2): PIDParams(K=1.0, Ti=5.0)}
    m = ControllerMatrix(1.0, pid=pi)
    run(m, 5)
    before = m.compute((0.5, 0.5), (0.4, 0.45))
    m.set_type(Family.PID, Structure.FULL_MATRIX)
    m.set_type(Family.PID, Structure.DECENTRALIZED)
    assert m.compute((0.5, 0.5), (0.4, 0.45)) == pytest.approx(before)
    m.set_type(Family.GENERAL, Structure.DECENTRALIZED)
    m.set_type(Family.PID, Structure.DECENTRALIZED)
    assert m.compute((0.5, 0.5), (0.4, 0.45)) == pytest.approx((0.1, 0.05))  # integrals gone


def test_reset_element_resets_only_that_one() -> None:
    pi = {(1, 1): PIDParams(K=1.0, Ti=5.0), (2, 2): PIDParams(K=1.0, Ti=5.0)}
    m = ControllerMatrix(1.0, pid=pi)
    run(m, 5)
    u1, u2 = m.compute((0.5, 0.5), (0.4, 0.45))
    m.reset_element(1, 1)
    assert m.compute((0.5, 0.5), (0.4, 0.45)) == pytest.approx((0.1, u2))
    m.reset()
    assert m.compute((0.5, 0.5), (0.4, 0.45)) == pytest.approx((0.1, 0.05))
    with pytest.raises(ParameterError):
        m.reset_element(3, 1)


def test_parameters_of_both_families_are_kept_per_element() -> None:
    m = ControllerMatrix(1.0)
    m.set_element_params(2, 1, PIDParams(K=-0.12, Ti=220.0))
    m.set_element_params(2, 1, GeneralParams(degree=1, s=(1.0, 0.5, 0, 0, 0), r=(0.1, 0, 0, 0)))
    assert m.pid_params(2, 1).K == -0.12
    assert m.general_params(2, 1).degree == 1


@pytest.mark.parametrize("family", [Family.PID, Family.GENERAL])
@pytest.mark.parametrize("structure", list(Structure))
def test_manual_to_automatic_is_bumpless(family: Family, structure: Structure) -> None:
    pi = PIDParams(K=2.0, Ti=30.0)
    pif = GeneralParams(degree=1, s=(2.0, 2.0 / 30.0, 0, 0, 0), r=(0.0, 0, 0, 0))
    elements = ((1, 1), (1, 2), (2, 1), (2, 2))
    m = ControllerMatrix(1.0, family, structure, pid={e: pi for e in elements},
                         general={e: pif for e in elements})
    r = (0.6, 0.6)
    y = (0.5, 0.55)
    u = (0.35, 0.4)
    for k in range(30):
        y = (0.5 + 0.001 * k, 0.55 + 0.0005 * k)
        m.compute(r, y)
        m.track(r, y, u)
    y1 = (y[0] + 0.001, y[1] + 0.0005)
    v = m.compute(r, y1)
    # Every active element moves only by its feedthrough times the error change.
    feed = 2.0 + (2.0 / 30.0 / 2.0 if family is Family.GENERAL else 0.0)
    per_input = feed * (0.001 + 0.0005) if structure is Structure.FULL_MATRIX else None
    for i in range(2):
        bound = per_input if per_input is not None else feed * (0.001, 0.0005)[i]
        assert abs(v[i] - u[i]) <= bound + 1e-12


def test_sampling_time_change_is_all_or_nothing() -> None:
    bad = GeneralParams(degree=1, s=(0.0, 1.0, 0, 0, 0), r=(-2.0, 0, 0, 0))  # pole at s = 2
    m = ControllerMatrix(0.5, Family.GENERAL, general={(1, 2): bad})
    with pytest.raises(ParameterError):
        m.set_sampling_time(1.0)  # 2/h = 2: Tustin maps the pole to infinity
    assert m.h == 0.5
    m.set_sampling_time(0.25)
    assert m.h == 0.25


def _full_pi(h: float = 1.0) -> ControllerMatrix:
    pid = {e: PIDParams(K=1.0 + 0.3 * n, Ti=20.0 + 5 * n, Td=2.0 * (n % 2), derivative=n % 2 == 1)
           for n, e in enumerate(((1, 1), (1, 2), (2, 1), (2, 2)))}
    return ControllerMatrix(h, Family.PID, Structure.FULL_MATRIX, pid=pid)


@pytest.mark.parametrize("family", [Family.PID, Family.GENERAL])
def test_update_after_compute_is_update_alone_bit_for_bit(family: Family) -> None:
    """update reuses this sample's compute (the engine's order: compute, write,
    update) only for the same r and y, and not across a change of the elements: the
    states come out as those of update alone, to the bit, over a saturating run with
    a change of parameters, a reset, a new sampling time, a change of structure and
    a Manual sample between a compute and its update."""
    rng = np.random.default_rng(3)
    cached, alone = _full_pi(), _full_pi()
    general = GeneralParams(degree=1, s=(0.5, 0.1, 0.0, 0.0, 0.0), r=(0.2, 0.0, 0.0, 0.0))
    for m in (cached, alone):
        m.set_element_params(2, 1, general)
        m.set_type(family, Structure.FULL_MATRIX)
    for k in range(500):
        r = tuple(rng.uniform(0.0, 1.0, 2))
        y = tuple(rng.uniform(0.0, 1.0, 2))
        u = saturate(cached.compute(r, y))
        assert u == saturate(alone.compute(r, y))
        if k == 100:
            for m in (cached, alone):
                m.set_element_params(1, 1, PIDParams(K=4.0, Ti=9.0))
        if k == 200:
            for m in (cached, alone):
                m.reset_element(2, 2)
        if k == 300:
            for m in (cached, alone):
                m.set_sampling_time(0.5)
        if k == 350:
            r = (r[0], r[1])  # equal values, another object: computed again
        if k == 400:
            for m in (cached, alone):
                m.set_type(family, Structure.DECENTRALIZED)
        if k == 450:
            for m in (cached, alone):
                m.track(r, y, u)
        alone.update((r[0], r[1]), (y[0], y[1]), u)  # other objects: never what compute saw
        cached.update(r, y, u)
        assert [(p.integral_state, p.derivative_state) for p in cached._pid.values()] == \
            [(p.integral_state, p.derivative_state) for p in alone._pid.values()]
        assert cached.compute((0.5, 0.5), (0.4, 0.6)) == alone.compute((0.5, 0.5), (0.4, 0.6))
