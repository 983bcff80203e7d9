"""The disturbance pumps in Simul (issue 29): the IST rig's two disturbance pumps
pour into tanks 1 and 2 (core.disturbance, after the rig's own simulator), and a
constant disturbance raises the steady state by what the nonlinear model says.

Hand computation, params/ist-lisbon.par (the published constants,
daq/ist/protocol.py), both pumps at 6 V.  At a steady state each tank's outflow
a_i sqrt(2 g h_i) is its inflow, so

    h1 = ((gamma1 k1 u1 + (1 - gamma2) k2 u2 + q1) / a1)^2 / (2 g)
    h2 = ((gamma2 k2 u2 + (1 - gamma1) k1 u1 + q2) / a2)^2 / (2 g)

and tanks 3, 4 are not touched.  Disturbance pump i at duty d gives
q = k1 c1 0.05 (d - c3) / (d - c2) cm^3/s (pump 1's c, k of pump.mat):

    d1 = 1 (255):         q1 = 3.13690 * 39.0102 * 0.05 * 0.966143 / 1.001240 = 5.90408 cm^3/s
    d2 = 0.5 -> 128/255:  q2 = 5.69181 cm^3/s
    inflows without:      tank 1: 0.756880 * 3.13690 * 6 + 0.243671 * 3.31423 * 6 = 19.0910 cm^3/s
                          tank 2: 0.756329 * 3.31423 * 6 + 0.243120 * 3.13690 * 6 = 19.6158 cm^3/s
    h1: 12.0531 -> ((19.0910 + 5.9041) / 0.124146)^2 / 1962 = 20.6609 cm   (+8.6078)
    h2: 10.7549 -> ((19.6158 + 5.6918) / 0.135037)^2 / 1962 = 17.9019 cm   (+7.1469)
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from quadtank_tui.core.disturbance import IST
from quadtank_tui.core.plants.johansson import steady_state_levels
from quadtank_tui.engine import commands as c
from quadtank_tui.engine.experiment import run_experiment
from quadtank_tui.engine.runner import build_engine
from quadtank_tui.files.par import read_par
from quadtank_tui.files.script import parse_script

ROOT = Path(__file__).parents[2]
PAR = ROOT / "params" / "ist-lisbon.par"
#: The hand-computed steady levels (module docstring), cm.
BEFORE = (12.0531, 10.7549)
AFTER = (20.6609, 17.9019)


def test_the_disturbance_law_against_the_hand_values() -> None:
    assert IST.flow(1.0) == pytest.approx(5.90408, abs=1e-5)
    assert IST.flow(128 / 255) == pytest.approx(5.69181, abs=1e-5)
    assert IST.flow(0.03) == 0.0  # below the pump's threshold c3 = 0.0339: nothing comes
    assert IST.inflow((1.0, 0.0)) == pytest.approx((5.90408, 0.0, 0.0, 0.0), abs=1e-5)  # pump i into tank i


def test_a_constant_disturbance_raises_the_steady_state_by_what_the_model_predicts(tmp_path: Path) -> None:
    params = read_par(PAR).params
    plant = params.quadtank_constants()
    start = steady_state_levels((6.0, 6.0), plant)
    assert start[:2] == pytest.approx(BEFORE, abs=1e-4)
    engine = build_engine(PAR, clock="manual", params_dir=ROOT / "params", logs_dir=tmp_path)
    script = parse_script("""
- at: 0
  set: {"REFERENCE ONE.Mean": 0.6, "REFERENCE TWO.Mean": 0.6}
- at: 0
  state: Run
- at: 10
  disturbance: {d1: 1.0, d2: 0.5}
""", name="disturb.yaml")
    with engine:
        engine.loop.place_at_steady_state(start)
        run_experiment(engine, script, 910.0)  # 18 time constants of tank 1 (49 s at 20 cm) after the event
        snap = engine.snapshot()
        assert engine.history()["y1"][9] == pytest.approx(0.25 * start[0] / 10, abs=1e-7)  # steady until then
        assert snap.disturbances == (1.0, 128 / 255)
        h = [y * 10.0 / plant.kc for y in snap.y]
        assert h[0] == pytest.approx(AFTER[0], abs=2e-4) and h[1] == pytest.approx(AFTER[1], abs=2e-4)
        assert h[2:] == pytest.approx(start[2:], abs=1e-6)  # the upper tanks feel nothing
        # and the safe states stop them: a Reset (and any fault, the end of the run)
        assert engine.submit(c.SetState("Reset")).result().ok
        assert engine.snapshot().disturbances == (0.0, 0.0)
        assert engine.loop.sim.disturbances == (0.0, 0.0)
    assert math.isclose(AFTER[0] - BEFORE[0], 8.6078, abs_tol=1e-4)


def test_a_process_without_disturbance_pumps_refuses_them(tmp_path: Path) -> None:
    engine = build_engine(ROOT / "params" / "coupled-tito.par", clock="manual", params_dir=ROOT / "params",
                          logs_dir=tmp_path)
    with engine:
        result = engine.submit(c.SetDisturbance(0.5, None)).result()
        assert not result.ok and result.message == ("the coupled-tito plant has no disturbance pumps (the IST "
                                                    "rig's pour into tanks 1 and 2 of the quadruple tank)")
        assert engine.snapshot().disturbances is None  # the Faults window shows no fields for them
