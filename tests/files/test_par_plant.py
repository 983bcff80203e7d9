"""The PLANT section of `.par` files: the plant is part of the parameters (issue 14)."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

import pytest

from quadtank_tui.core.parameters import PLANT_SETTINGS, PRESET
from quadtank_tui.core.plants import CoupledCascade, CoupledTITO, DesautelQTP, QuadTank
from quadtank_tui.files.par import ParFileError, format_par, parse_par, read_par

PARAMS = Path(__file__).resolve().parents[2] / "params"
STAMP = datetime(2026, 11, 22, 12, 0, 0)


@pytest.mark.parametrize("name", ["default", "minphase", "nonminphase"])
def test_old_files_load_as_the_quadruple_tank(name: str) -> None:
    p = read_par(PARAMS / f"{name}.par").params
    assert p.process is None
    assert p.process_plant() == QuadTank(p.quadtank_constants())
    assert "PLANT" not in (PARAMS / f"{name}.par").read_text()


@pytest.mark.parametrize("name, cls", [("coupled-cascade", CoupledCascade), ("coupled-tito", CoupledTITO),
                                       ("desautel-qtp", DesautelQTP)])
def test_shipped_plant_presets(name: str, cls: type) -> None:
    read = read_par(PARAMS / f"{name}.par")
    assert read.warnings == ()
    assert read.params == PLANT_SETTINGS[name]
    assert read.params.process_plant() == cls()


def test_preset_operating_points() -> None:
    ctp = PLANT_SETTINGS["coupled-cascade"]
    assert ctp.process_levels() == pytest.approx((15.0, 14.727394), abs=1e-6)
    assert ctp.references[0].mean == pytest.approx(6.769218 / 22.0, abs=1e-6)
    tito = PLANT_SETTINGS["coupled-tito"]
    assert tito.process_levels() == (0.115, 0.071)
    assert [c.pid.K for c in tito.controllers] == [31.0, 0.0, 0.0, 5.6]
    assert [tito.controllers[0].pid.Ti, tito.controllers[3].pid.Ti] == [6.2, 10.0]
    assert tito.control.mode.value == "Automatic"
    assert [r.mean for r in tito.references] == pytest.approx([33.33 * 0.115 / 10, 33.33 * 0.071 / 10], abs=1e-6)
    qtp = PLANT_SETTINGS["desautel-qtp"]
    assert qtp.process_levels() == pytest.approx((12.8746, 13.0708, 7.2503, 5.1228), abs=1e-4)


def test_round_trip_is_exact() -> None:
    for p in PLANT_SETTINGS.values():
        text = format_par(p, STAMP)
        back = parse_par(text)
        assert back.params == p and format_par(back.params, STAMP) == text


def test_a_partial_plant_section_takes_the_plant_defaults() -> None:
    text = "% TANK PAR-file\n\nPLANT\nKind coupled-cascade\nbeta1 0.3\nLevel1 10\nLevel2 9.5\n"
    p = parse_par(text).params
    assert p.process_plant() == CoupledCascade(beta1=0.3)
    assert p.process_levels() == (10.0, 9.5)
    assert p.tsamp_ms == PRESET.tsamp_ms  # the other sections keep the base's values


def test_a_file_without_plant_section_is_the_quadruple_tank_whatever_the_base() -> None:
    text = (PARAMS / "minphase.par").read_text()
    p = parse_par(text, base=PLANT_SETTINGS["coupled-tito"]).params
    assert p.process is None and p.process_plant() == QuadTank(p.quadtank_constants())


def test_kind_quadtank_is_the_simulation_section() -> None:
    p = parse_par("% TANK PAR-file\n\nPLANT\nKind quadtank\n").params
    assert p.process is None


@pytest.mark.parametrize("body, line, key, reason", [
    ("Kind triple-tank\n", 4, "PLANT.Kind", "must be one of"),
    ("Kind coupled-cascade\nalpha1 -0.1\nLevel1 1\nLevel2 1\n", 5, "PLANT.alpha1", "> 0"),
    ("Kind coupled-cascade\nalpha1 abc\nLevel1 1\nLevel2 1\n", 5, "PLANT.alpha1", "not a number"),
    ("Kind coupled-cascade\nLevel1 1\nLevel2 40\n", 6, "PLANT.Level2", "(0, 30]"),
    ("Kind coupled-cascade\nLevel1 1\n", 4, "PLANT.Level2", "every operating level"),
    ("Kind coupled-tito\nalpha1 1\nLevel1 0.1\nLevel2 0.1\n", 5, "PLANT.alpha1", "no constant"),
    ("Kind coupled-tito\nLevel1 0.1\nLevel1 0.1\n", 6, "PLANT.Level1", "duplicate"),
    ("beta1 0.2\n", 4, "PLANT.Kind", "must name the plant"),
    ("Kind quadtank\nk1 3\n", 5, "PLANT.k1", "SIMULATION"),
])
def test_bad_plant_sections_name_line_and_key(body: str, line: int, key: str, reason: str) -> None:
    with pytest.raises(ParFileError) as err:
        parse_par("% TANK PAR-file\n\nPLANT\n" + body, name="x.par")
    assert (err.value.line, err.value.key) == (line, key)
    assert reason in err.value.reason
