"""The simulator starts at rest: Manual with nothing touched holds the levels, for
10 minutes, to better than the screen's 3 decimals (issue 43).  The steady state is
worked out here from the orifice law by hand (h = (q / a)^2 / 2g, upper tanks first),
not by the plant code the engine uses."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from quadtank_tui.engine import commands as c
from quadtank_tui.engine.runner import build_engine
from quadtank_tui.files.par import read_par

REPO = Path(__file__).resolve().parents[2]


def _by_hand(par: Path) -> list[float]:
    """Normalized levels y = kc h / 10 at the file's Manual inputs (10 V x mean)."""
    p = read_par(par).params
    s = p.simulation
    g = 981.0
    h0 = [op * 10.0 / s.sensor for op in s.op_points]
    areas = [math.pi * d * d / 4.0 for d in s.diameters]
    outlets = [areas[i] * math.sqrt(2.0 * h0[i] / g) / s.time_constants[i] for i in range(4)]
    v1, v2 = (10.0 * r.mean for r in p.references)
    (g1, g2), (k1, k2) = s.valves, s.pumps
    q3, q4 = (1 - g2) * k2 * v2, (1 - g1) * k1 * v1
    q1, q2 = g1 * k1 * v1 + q3, g2 * k2 * v2 + q4
    h = [(q / a) ** 2 / (2.0 * g) for q, a in zip((q1, q2, q3, q4), outlets)]
    return [s.sensor * x / 10.0 for x in h]


@pytest.mark.parametrize("name", ["default.par", "minphase.par", "nonminphase.par"])
def test_manual_with_nothing_touched_holds_the_levels_for_600_s(tmp_path: Path, name: str) -> None:
    (tmp_path / "logs").mkdir()
    engine = build_engine(REPO / "params" / name, clock="manual", params_dir=REPO / "params",
                          logs_dir=tmp_path / "logs")
    start = engine.snapshot().y
    assert start == pytest.approx(_by_hand(REPO / "params" / name), abs=1e-6)
    assert engine.submit(c.SetState("Run")).result().ok
    engine.run_for(600.0)
    after = engine.snapshot()
    assert after.state == "Run" and after.u == tuple(r.mean for r in read_par(REPO / "params" / name).params.references)
    assert max(abs(a - b) for a, b in zip(start, after.y)) < 5e-4, (start, after.y)


def test_default_par_starts_at_its_inputs_steady_state_not_its_rounded_op_points(tmp_path: Path) -> None:
    (tmp_path / "logs").mkdir()
    engine = build_engine(REPO / "params" / "default.par", clock="manual", params_dir=REPO / "params",
                          logs_dir=tmp_path / "logs")
    assert [round(y, 4) for y in engine.snapshot().y] == [0.6131, 0.6392, 0.0817, 0.0705]
    # the file's operating point is kept for the model (outlets, linearization)
    assert engine.snapshot().params.simulation.op_points == (0.62, 0.635, 0.09, 0.07)


def test_a_file_saved_in_automatic_starts_at_its_operating_point(tmp_path: Path) -> None:
    """Its means are references (coupled-tito.par: 0.383), not pump inputs."""
    (tmp_path / "logs").mkdir()
    par = REPO / "params" / "coupled-tito.par"
    engine = build_engine(par, clock="manual", params_dir=REPO / "params", logs_dir=tmp_path / "logs")
    params = read_par(par).params
    plant = params.process_plant()
    assert engine.snapshot().y[:2] == pytest.approx(
        [v / 10.0 for v in plant.output(params.process_levels())][:2], abs=1e-9)
