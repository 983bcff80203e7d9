"""The simulator backend and headless runs with every plant (issue 14)."""

from __future__ import annotations

from pathlib import Path

import pytest

from quadtank_tui.cli import main
from quadtank_tui.core.plants import johansson as qt
from quadtank_tui.core.plants import CoupledCascade, CoupledTITO, QuadTank
from quadtank_tui.engine.sim import SimBackend
from quadtank_tui.files.log_reader import read_log

PARAMS = Path(__file__).resolve().parents[2] / "params"


def test_cascade_io_scales() -> None:
    """y = sensor volts / 10 (y3, y4 read 0), u = 1 is the amplifier's 22 V."""
    p = CoupledCascade()
    sim = SimBackend.for_plant(p, (15.0, 14.0))
    assert sim.read_levels() == pytest.approx((15.0 / 5.4310 / 10, 14.0 / 5.5558 / 10, 0.0, 0.0))
    sim.write_pumps((0.5, 0.9))
    assert sim.voltages == (11.0,)
    sim.elapse(7.0)
    assert sim.levels_cm == p.advance((15.0, 14.0), (11.0,), 7.0)
    sim.add_water(2, 0.1)  # 1 V of sensor 2 = 5.5558 cm
    assert sim.levels_cm[1] == pytest.approx(p.advance((15.0, 14.0), (11.0,), 7.0)[1] + 5.5558)
    with pytest.raises(qt.PlantError):
        sim.add_water(3, 0.1)
    with pytest.raises(qt.PlantError, match="not the quadruple tank"):
        sim.params  # noqa: B018
    sim.reset()
    assert sim.levels_cm == (15.0, 14.0) and sim.voltages == (0.0,)


def test_a_four_tank_plant_starts_at_its_operating_levels() -> None:
    from quadtank_tui.core.plants import DesautelQTP

    p = DesautelQTP()
    x = p.steady_state((6.0, 6.0))
    sim = SimBackend.for_plant(p, x)
    assert sim.levels_cm == x
    assert sim.read_levels() == pytest.approx(tuple(h / 3 / 10 for h in x))
    sim.write_pumps((6 / 22, 6 / 22))
    sim.elapse(50.0)
    assert sim.levels_cm == pytest.approx(x, abs=1e-6)


def test_switching_plants_keeps_what_fits() -> None:
    sim = SimBackend(qt.P_MINUS.params, qt.P_MINUS.op.x)
    sim.set_plant(CoupledTITO(), (0.115, 0.071))
    assert sim.levels_cm == (0.115, 0.071) and sim.plant == CoupledTITO()
    sim.set_plant(CoupledTITO(Cd2=0.3))  # an outlet changed: the water stays
    assert sim.levels_cm == (0.115, 0.071)
    sim.set_plant(QuadTank(qt.P_PLUS.params), qt.P_PLUS.op.x)
    assert sim.levels_cm == qt.P_PLUS.op.x and sim.params == qt.P_PLUS.params
    sim.write_pumps((0.3, 0.3))
    sim.elapse(2.0)
    assert sim.levels_cm == qt.advance(qt.P_PLUS.op.x, (3.0, 3.0), 2.0, qt.P_PLUS.params)


def test_headless_run_of_murray_smith_preset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """His controllers hold H1 = 0.115 m; H2 cannot be held at 0.071 m (the drain
    passes less than the orifice there: pump 2 would have to run backwards), so it
    settles where pump 2 is off: H2 = (c1^2 H1 + c2^2 H3) / (c1^2 + c2^2) = 0.0771 m,
    c_i = Cd_i a_i."""
    out = tmp_path / "tito.log"
    assert main(["run", "--par", str(PARAMS / "coupled-tito.par"), "--duration", "600", "--log", str(out)]) == 0
    log = read_log(out)
    p = CoupledTITO()
    c1, c2 = (p.Cd1 * p.a1) ** 2, (p.Cd2 * p.a2) ** 2
    h2 = (c1 * 0.115 + c2 * p.H3) / (c1 + c2)
    assert log.data[-1][0] == pytest.approx(p.Gd * 0.115 / 10, abs=1e-4)
    assert log.data[-1][1] == pytest.approx(p.Gd * h2 / 10, abs=1e-3)
    assert log.data[-1][3] == 0.0  # u2 saturated at 0


def test_headless_run_of_the_cascade_stays_at_its_operating_point(tmp_path: Path) -> None:
    out = tmp_path / "ctp.log"
    assert main(["run", "--par", str(PARAMS / "coupled-cascade.par"), "--duration", "100", "--log", str(out)]) == 0
    last = read_log(out).data[-1]
    assert last[0] * 10 * 5.4310 == pytest.approx(15.0, abs=1e-4)
    assert last[1] * 10 * 5.5558 == pytest.approx(14.7274, abs=1e-3)


def test_loading_a_par_switches_the_simulated_plant(make_engine, tmp_path: Path) -> None:
    from quadtank_tui.engine.commands import LoadPar, SetState
    from quadtank_tui.files.shipped import write_shipped

    write_shipped(tmp_path / "params")
    e = make_engine()
    assert e.submit(LoadPar("coupled-tito")).result().ok
    assert e.loop.sim.plant == CoupledTITO()
    e.submit(SetState("Run"))
    e.step(1)
    assert e.snapshot().y[:2] == pytest.approx((33.33 * 0.115 / 10, 33.33 * 0.071 / 10), abs=1e-3)
    assert e.snapshot().y[2:] == (0.0, 0.0)
    assert e.submit(LoadPar("minphase")).result().ok
    assert e.loop.sim.plant == QuadTank(e.snapshot().params.quadtank_constants())
    e.step(1)
    assert len(e.loop.sim.levels_cm) == 4
