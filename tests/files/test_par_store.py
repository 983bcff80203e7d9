"""The params/ folder: names not paths, `default` and `preset` reserved, defaults
falling back to the built-ins with a warning."""

from __future__ import annotations

import shutil
from datetime import datetime
from pathlib import Path

import pytest

from quadtank_tui.core.parameters import NAMED_SETTINGS, PRESET
from quadtank_tui.files.par import ParFileError, ParStore, format_par

PARAMS = Path(__file__).parents[2] / "params"
STAMP = datetime(2026, 1, 2, 3, 4, 5)


@pytest.fixture
def store(tmp_path: Path) -> ParStore:
    folder = tmp_path / "params"
    shutil.copytree(PARAMS, folder)
    return ParStore(folder)


def test_names_of_the_shipped_folder(store: ParStore) -> None:
    assert store.names() == ["coupled-cascade", "coupled-tito", "default", "desautel-qtp", "ist-lisbon", "minphase",
                             "nonminphase"]
    assert ParStore(store.folder / "missing").names() == []


def test_load_named_settings(store: ParStore) -> None:
    read = store.load("nonminphase")
    assert read.params == NAMED_SETTINGS["nonminphase"]
    assert read.warnings == ()
    assert store.load("minphase.par").params == PRESET


def test_preset_and_default(store: ParStore) -> None:
    assert store.load("preset").params == PRESET
    custom = PRESET.with_value("SAMPLING TIME.TSamp", 250)
    (store.folder / "default.par").write_text(format_par(custom, STAMP))
    assert store.load("default").params == custom
    assert store.load("preset").params == PRESET
    assert store.defaults().params == custom


def test_missing_values_in_a_named_file_take_the_defaults(store: ParStore) -> None:
    custom = PRESET.with_value("SAMPLING TIME.TSamp", 250)
    (store.folder / "default.par").write_text(format_par(custom, STAMP))
    (store.folder / "valves.par").write_text("SIMULATION\nValve1 0.4\n")
    p = store.load("valves").params
    assert (p.tsamp_ms, p.simulation.valves[0]) == (250.0, 0.4)
    assert p.modified_keys(store.defaults().params) == {"SIMULATION.Valve1"}


def test_default_missing_falls_back_to_preset_with_a_warning(store: ParStore) -> None:
    (store.folder / "default.par").unlink()
    read = store.load("default")
    assert read.params == PRESET
    assert read.warnings == (f"{store.folder / 'default.par'} not found: using the built-in (preset) values",)


def test_default_broken_falls_back_to_preset_with_a_warning(store: ParStore) -> None:
    (store.folder / "default.par").write_text("SIMULATION\nValve1 7\n")
    read = store.load("default")
    assert read.params == PRESET
    assert read.warnings == (
        f"{store.folder / 'default.par'}, line 2: SIMULATION.Valve1: must be <= 1, got 7; "
        "using the built-in (preset) values instead",
    )


def test_a_broken_named_file_is_refused(store: ParStore) -> None:
    (store.folder / "bad.par").write_text("SIMULATION\nValve1 7\n")
    with pytest.raises(ParFileError) as info:
        store.load("bad")
    assert (info.value.line, info.value.key) == (2, "SIMULATION.Valve1")


def test_save_and_ask_before_overwriting(store: ParStore) -> None:
    p = PRESET.with_value("CONTROLLER ONE.K", 2.2)
    assert not store.exists("mine")
    path = store.save("mine", p, created=STAMP)
    assert path == store.folder / "mine.par"
    assert store.exists("mine") and store.exists("mine.par")
    assert store.load("mine").params == p
    assert "mine" in store.names()


@pytest.mark.parametrize("name", ["default", "Default", "default.par", "preset", "PRESET"])
def test_reserved_names_cannot_be_saved(store: ParStore, name: str) -> None:
    before = (store.folder / "default.par").read_bytes()
    with pytest.raises(ParFileError, match="is reserved"):
        store.save(name, PRESET.with_value("CONTROLLER ONE.K", 1.0))
    assert (store.folder / "default.par").read_bytes() == before
    assert not (store.folder / "preset.par").exists()


def test_reserved_reasons_are_explained(store: ParStore) -> None:
    with pytest.raises(ParFileError) as info:
        store.save("default", PRESET)
    assert str(info.value) == (
        "default: 'default' is reserved: it holds everyone's defaults and is not overwritten by a normal "
        "save (copy a saved file to default.par to change them)"
    )
    with pytest.raises(ParFileError) as info:
        store.save("preset", PRESET)
    assert str(info.value) == "preset: 'preset' is reserved: it names the built-in values, which no file replaces"


@pytest.mark.parametrize("name", ["../x", "a/b", "..", ".hidden", "/etc/passwd", "a\\b", "", "x\x00y", "sub/../x"])
def test_names_that_would_leave_the_folder_are_refused(store: ParStore, name: str) -> None:
    with pytest.raises(ParFileError, match="a parameter file name must be a plain file name"):
        store.save(name, PRESET)
    with pytest.raises(ParFileError):
        store.load(name)
    assert sorted(p.name for p in store.folder.parent.iterdir()) == ["params"]
