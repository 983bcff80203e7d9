"""State feedback through the loop on the coupled tanks (Desautel's CTP, Murray-Smith's
two-input rig), on the nonlinear simulator.

The CTP comes from the shipped params/coupled-cascade.par (x1 = 15 cm, T = 0.1 s):
levels in cm are y * 10 / kc_i, the pump is u * vmax (22 V).  The lower tank,
the one the integrator tracks, follows REFERENCE TWO.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from quadtank_tui.core.parameters import Parameters
from quadtank_tui.core.plants import CoupledCascade, CoupledTITO
from quadtank_tui.core.plants.spec import PlantSpec
from quadtank_tui.core.controllers.statefb.tracking import u_ssmax
from quadtank_tui.core.controllers.statefb.placement import loop_margins
from quadtank_tui.core.controllers.statefb.plants import PlantStateFeedback
from quadtank_tui.engine.commands import Command, SetControlMode, SetParams, SetState
from quadtank_tui.engine.loop import ControlLoop
from quadtank_tui.files.par import read_par

ROOT = Path(__file__).parents[2]
CASCADE = read_par(ROOT / "params" / "coupled-cascade.par").params
TITO = read_par(ROOT / "params" / "coupled-tito.par").params


def ok(loop: ControlLoop, command: Command) -> None:
    result = loop.apply(command)
    assert result.ok, result.message


def ctp(ts: float = 20.0, *, smart: bool = True, vmax: float = 22.0) -> Parameters:
    p = CASCADE.with_values({"CONTROL.Type": "State feedback", "STATE FEEDBACK.Ts": ts,
                             "STATE FEEDBACK.Smart": smart, "STATE FEEDBACK.L3": 1.385,
                             "REFERENCE ONE.Mean": 0.0})
    if vmax != 22.0:
        p = dataclasses.replace(p, process=PlantSpec.of(CoupledCascade(vmax=vmax), p.process_levels()))
    return p


def the_statefb(loop: ControlLoop) -> PlantStateFeedback:
    sf = loop.statefb
    assert isinstance(sf, PlantStateFeedback), loop.fault
    return sf


def test_the_cascade_design_in_the_loop_is_desautels_3_4() -> None:
    """T = 0.1 s, Ts = 20 s at x1 = 15 cm: his poles, z-poles, L_d and phase margin."""
    loop = ControlLoop(ctp())
    assert loop.fault is None and loop.h == 0.1
    d = the_statefb(loop).controller.design
    np.testing.assert_allclose(d.poles_s, [-0.25047, -0.19834 + 0.18922j, -0.19834 - 0.18922j], atol=6e-6)
    np.testing.assert_allclose(d.placed_poles(), [0.97526, 0.98019 + 0.01855j, 0.98019 - 0.01855j], atol=6e-6)
    np.testing.assert_allclose(d.L[0], [2.1179, 9.9757, 0.13191], rtol=5e-5)
    assert round(loop_margins(d).phase_margin) == 67
    info = loop.snapshot().statefb
    assert info is not None and info.L2 == ((pytest.approx(0.13191, abs=1e-5),),)
    assert info.x_e == pytest.approx((15.0, 14.727394), abs=1e-6)


def test_the_cascade_level_limit_is_his_u_ssmax() -> None:
    """Tank 1 (the pump's) is capped at U_ssmax = alpha1 sqrt(2 g x) / beta1 (3.2.2),
    x = 30 - 1.5 * 2 cm, above 30 - 2 cm; tank 2 has no pump of its own."""
    (lim,) = the_statefb(ControlLoop(ctp())).controller.level_limits
    plant = CoupledCascade()
    assert (lim.state, lim.pump, lim.trigger) == (0, 0, 28.0)
    assert lim.u_hold == pytest.approx(u_ssmax(plant.alpha1, plant.beta1, 27.0), rel=1e-9)


def run_series(p: Parameters, refs: tuple[float, ...], seconds: float) -> np.ndarray:
    """From empty tanks, Automatic with REFERENCE TWO stepping through `refs` (cm of
    tank 2), `seconds` each; rows (r, x1, x2, u volts)."""
    loop = ControlLoop(p)
    plant = loop.sim.plant
    assert isinstance(plant, CoupledCascade)
    loop.place_at_steady_state((0.0, 0.0))
    ok(loop, SetState("Run"))
    loop.step()
    ok(loop, SetControlMode("Automatic"))
    rows = []
    for r in refs:
        ok(loop, SetParams({"REFERENCE TWO.Mean": plant.kc2 * r / 10}))
        for _ in range(round(seconds / loop.h)):
            s = loop.step()
            rows.append((r, s.y[0] * 10 / plant.kc1, s.y[1] * 10 / plant.kc2, s.u[0] * plant.vmax))
    return np.array(rows)


def test_his_step_series_from_empty_tracks_with_zero_steady_state_error() -> None:
    """12, 20, 16 cm, each held 150 s (Ts = 20 s): tank 2 ends on each reference."""
    rows = run_series(ctp(), (12.0, 20.0, 16.0), 150.0)
    ends = [rows[k * 1500 - 1, 2] for k in (1, 2, 3)]
    assert ends == pytest.approx([12.0, 20.0, 16.0], abs=1e-3), ends


def test_with_the_pump_limit_the_smart_integrator_overshoots_less_than_the_plain_one() -> None:
    """His series at 45 s intervals with the pump limited to 12 V: the fill rate
    saturates, the plain integrator winds up and overshoots."""
    over, top = {}, {}
    for smart in (True, False):
        rows = run_series(ctp(smart=smart, vmax=12.0), (12.0, 20.0, 16.0), 45.0)
        top[smart] = float(rows[:, 3].max())
        over[smart] = [round(float(rows[a:a + 450, 2].max() - r), 3) for a, r in ((0, 12.0), (450, 20.0))]
    msg = f"overshoot of tank 2 (cm) after the 12 and 20 cm steps: smart {over[True]}, plain {over[False]}"
    assert top[True] == top[False] == pytest.approx(12.0), f"the pump limit is not active: {top}; {msg}"
    assert max(over[True]) < 0.3 and min(over[False]) > 0.5, msg
    assert over[True][0] < over[False][0] and over[True][1] < over[False][1], msg


def tito(levels: tuple[float, float] = (0.15, 0.10)) -> Parameters:
    p = TITO.with_values({"CONTROL.Type": "State feedback", "STATE FEEDBACK.Ts": 60.0})
    return dataclasses.replace(p, process=PlantSpec.of(CoupledTITO(), levels))


def test_the_two_input_rig_places_four_poles_and_tracks_both_tanks() -> None:
    """Two pumps, two levels (m), an integrator per tank: the 4 Bessel poles of Ts 60 s."""
    loop = ControlLoop(tito())
    d = the_statefb(loop).controller.design
    assert d.L.shape == (2, 4)
    np.testing.assert_allclose(np.sort_complex(d.placed_poles()), np.sort_complex(np.exp(d.poles_s * 0.1)),
                               atol=1e-9)
    np.testing.assert_allclose(np.sort_complex(d.poles_s), np.sort_complex(
        [-4.0156 / 60 + 5.0723j / 60, -4.0156 / 60 - 5.0723j / 60,
         -5.5281 / 60 + 1.6553j / 60, -5.5281 / 60 - 1.6553j / 60]), atol=1e-12)
    assert 0.5 < d.delta < 1.0
    gd = CoupledTITO().Gd
    ok(loop, SetState("Run"))
    ok(loop, SetControlMode("Automatic"))
    for r1, r2 in ((0.16, 0.11), (0.14, 0.10)):
        ok(loop, SetParams({"REFERENCE ONE.Mean": gd * r1 / 10, "REFERENCE TWO.Mean": gd * r2 / 10}))
        for _ in range(3000):
            s = loop.step()
        assert (s.y[0] * 10 / gd, s.y[1] * 10 / gd) == pytest.approx((r1, r2), abs=1e-6)


def test_levels_no_pump_can_hold_are_refused_naming_the_plant_level() -> None:
    """Murray-Smith's point (0.115, 0.071) m needs pump 2 to run backwards here: the
    file starts with the PID and the snapshot says why; a SetParams is refused."""
    p = tito((0.115, 0.071))
    loop = ControlLoop(p)
    assert loop.statefb is None and loop.fault is not None
    assert "PLANT.Level1" in loop.fault and "backwards" in loop.fault, loop.fault
    result = loop.apply(SetParams({"CONTROL.Type": "State feedback"}))
    assert not result.ok and "PLANT.Level1" in result.message


def test_switching_to_state_feedback_on_the_cascade_is_bumpless() -> None:
    """Manual at the operating pump voltage, then Automatic, then the type: u holds."""
    loop = ControlLoop(CASCADE.with_values({"CONTROL.Mode": "Manual"}))
    ok(loop, SetState("Run"))
    for _ in range(200):
        loop.step()
    ok(loop, SetControlMode("Automatic"))
    loop.step()
    before = loop.snapshot().u
    ok(loop, SetParams({"CONTROL.Type": "State feedback", "STATE FEEDBACK.Ts": 20.0}))
    assert loop.step().u == pytest.approx(before, abs=1e-3)
    ok(loop, SetParams({"STATE FEEDBACK.Ts": 40.0}))  # a redesign between samples
    assert loop.step().u == pytest.approx(before, abs=1e-3)
    assert math.isclose(the_statefb(loop).settings.settling_time, 40.0)
