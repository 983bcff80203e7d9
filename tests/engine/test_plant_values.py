"""The plant in use edited while it runs (issue 14): "PLANT.<key>" values through
SetParams, all or none, applied between samples, refused with the key and the
reason, and kept by a saved `.par`."""

from __future__ import annotations

from pathlib import Path

import pytest

from quadtank_tui.core.parameters import PLANT_SETTINGS
from quadtank_tui.core.plants import CoupledCascade
from quadtank_tui.engine.commands import SavePar, SetParams, SetState
from quadtank_tui.engine.runner import build_engine
from quadtank_tui.files.par import format_par

PARAMS = Path(__file__).resolve().parents[2] / "params"

#: What params/coupled-cascade.par's PLANT section becomes with alpha1 = 0.0105 and
#: vmax = 24: x2 follows x1 = 15 cm at steady state, x2 = (alpha1 / alpha2)^2 x1.
EDITED_PLANT = """\
PLANT
Kind coupled-cascade
alpha1 0.010500
alpha2 0.0098811
beta1 0.248130
g 981.000000
hmax 30.000000
kc1 0.18412815319462345
kc2 0.17999208034846467
vmax 24.000000
Level1 15.000000
Level2 16.937888442299226
"""


def cascade_engine(tmp_path: Path):
    folder = tmp_path / "params"
    folder.mkdir()
    (folder / "default.par").write_text((PARAMS / "default.par").read_text())
    return build_engine(PARAMS / "coupled-cascade.par", clock="manual", params_dir=folder,
                        logs_dir=tmp_path / "logs")


def test_a_plant_value_set_while_running_changes_the_process_and_the_saved_par(tmp_path: Path) -> None:
    engine = cascade_engine(tmp_path)
    assert engine.submit(SetState("Run")).result().ok
    engine.run_for(1.0)
    before = engine.loop.sim.levels_cm
    result = engine.submit(SetParams({"PLANT.alpha1": 0.0105, "PLANT.vmax": 24.0})).result()
    assert result.ok, result.message
    plant = engine.loop.sim.plant
    assert plant == CoupledCascade(alpha1=0.0105, vmax=24.0)
    assert engine.loop.sim.levels_cm == before  # the water stays where it is
    assert engine.params.process_levels()[1] == pytest.approx(15.0 * (0.0105 / 0.0098811) ** 2, rel=1e-12)
    assert engine.submit(SavePar("edited")).result().ok
    text = (tmp_path / "params" / "edited.par").read_text()
    assert text.endswith("\n" + EDITED_PLANT)
    assert text == format_par(engine.params, _created(text))


def _created(text: str):
    from datetime import datetime

    line = text.splitlines()[1].removeprefix("% Created on: ")
    return datetime.strptime(line, "%b %d %H:%M:%S %Y")


@pytest.mark.parametrize("values, message", [
    ({"PLANT.alpha1": -0.01}, "PLANT.alpha1: alpha1 must be a finite number > 0, got -0.01"),
    ({"PLANT.alpha1": 0.011, "PLANT.hmax": 10.0}, "PLANT.Level1: operating level x1 must be in (0, 10] cm, got 15"),
    ({"PLANT.A1": 1.0}, "PLANT.A1: a coupled-cascade plant has no value 'A1' (it has alpha1, alpha2, beta1, "
                        "g, hmax, kc1, kc2, vmax, spill1, vmin, ysat1, ysat2, lam1, lam2, area1, off1, off2, Level1, Level2)"),
    ({"PLANT.kc1": "x"}, "PLANT.kc1: must be a number, got 'x'"),
])
def test_a_refused_plant_value_changes_nothing_and_says_why(tmp_path: Path, values: dict, message: str) -> None:
    engine = cascade_engine(tmp_path)
    before = engine.params
    result = engine.submit(SetParams(values)).result()
    assert (result.ok, result.message) == (False, message)
    assert engine.params == before and engine.loop.sim.plant == CoupledCascade()


def test_the_quadruple_tank_has_no_plant_section_values(tmp_path: Path) -> None:
    engine = build_engine(PARAMS / "default.par", clock="manual", params_dir=PARAMS)
    result = engine.submit(SetParams({"PLANT.alpha1": 0.01})).result()
    assert not result.ok and result.message.startswith("PLANT.alpha1: the quadruple tank's values are set in SIMULATION")


def test_the_two_input_rig_redesigned_between_samples(tmp_path: Path) -> None:
    """Murray-Smith's orifice a1 enlarged 10 %: the loop's next sample runs the new
    plant (his robustness tests change exactly these areas)."""
    engine = build_engine(PARAMS / "coupled-tito.par", clock="manual", params_dir=PARAMS)
    assert engine.submit(SetParams({"PLANT.a1": 3.956e-5 * 1.1})).result().ok
    assert engine.loop.sim.plant.values()["a1"] == pytest.approx(4.3516e-5)
    process = engine.params.process
    preset = PLANT_SETTINGS["coupled-tito"].process
    assert process is not None and preset is not None and process.levels == preset.levels
