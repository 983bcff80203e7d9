"""Loading a `.par` in Automatic does not move the references (issue 23).

As a new user tried it: Automatic, Run, then nonminphase.par (saved in Manual, its
means the pumps' 0.315).  The file's means became ref1 and ref2 and the tanks at
0.63 drained towards 0.38.  Now the references keep the means in force, the rest
of the file loads (controllers, valves), and the levels stay where they were; in
Manual the file's means still set the pumps (its operating point).  Both ways a
LoadPar reaches the loop are covered: read on the loop's thread (a manual clock)
and read off it (InstallPar from engine/parload.py).
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.engine.commands import Command, LoadPar, SetControlMode, SetState
from quadtank_tui.engine.runner import Engine

SHIPPED = Path(__file__).resolve().parents[2] / "params" / "nonminphase.par"
MEANS = ("REFERENCE ONE.Mean", "REFERENCE TWO.Mean")

MakeEngine = Callable[..., Engine]


def ok(engine: Engine, command: Command) -> str:
    result = engine.submit(command).result(timeout=20)
    assert result.ok, result.message
    return result.message


@pytest.fixture
def params_dir(tmp_path: Path) -> Path:
    folder = tmp_path / "params"
    folder.mkdir()
    shutil.copy(SHIPPED, folder / "nonminphase.par")
    return folder


def automatic_at_rest(engine: Engine) -> tuple[float, float]:
    """Manual at the preset's operating point for 10 s, then Automatic for 20 s;
    the references in force."""
    ok(engine, SetState("Run"))
    engine.step(100)
    ok(engine, SetControlMode("Automatic"))
    engine.step(200)
    s = engine.snapshot()
    return s.r[0], s.r[1]


def test_loading_in_automatic_keeps_the_references(make_engine: MakeEngine, params_dir: Path) -> None:
    e = make_engine(params_dir=params_dir)
    r0 = automatic_at_rest(e)
    u0 = e.snapshot().u
    message = ok(e, LoadPar("nonminphase"))
    assert r0 == pytest.approx((0.62, 0.635), abs=0.005)
    p = e.snapshot().params
    assert (p.get(MEANS[0]), p.get(MEANS[1])) == pytest.approx(r0)
    # the rest of the file is in force: its controllers and its valves (P+)
    assert p.get("CONTROLLER ONE.Ti") == 110.0 and p.get("CONTROLLER FOUR.K") == -0.12
    assert p.get("SIMULATION.Valve1") == 0.43
    assert e.snapshot().control == "Automatic"
    e.step(1)
    assert e.snapshot().u == pytest.approx(u0, abs=0.01)  # was (0.0, 0.34): u1 fell from 0.30
    lowest = [1.0, 1.0]
    for _ in range(60):  # 60 s: the file's means drained y1 from 0.62 to 0.44 in this time
        e.step(10)
        s = e.snapshot()
        assert s.r == pytest.approx(r0)
        lowest = [min(lowest[i], s.y[i]) for i in (0, 1)]
    # the valves of P+ disturb the loop (the file changes the plant), it does not steer away
    assert min(lowest) > 0.55, lowest
    # and the user is told (on any screen: the notification of the load)
    assert f"references kept at {r0[0]:.3f}, {r0[1]:.3f}" in message
    assert "the file's means 0.315, 0.315 not applied" in message


def test_loading_in_manual_sets_the_files_inputs(make_engine: MakeEngine, params_dir: Path) -> None:
    """Manual: the file's means are the inputs of its operating point, as before."""
    e = make_engine(params_dir=params_dir)
    assert ok(e, LoadPar("nonminphase")) == "loaded nonminphase"
    ok(e, SetState("Run"))
    e.step(2)
    assert e.snapshot().u == pytest.approx((0.315, 0.315))
