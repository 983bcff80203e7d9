"""File and screen names (a log's file name, its columns, the plot types) are
checked by files.names, not by the core (issue 18): every way in still refuses a
bad one, naming the key (and the file and line where there is one)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.engine.commands import SetParams
from quadtank_tui.engine.runner import Engine, build_engine
from quadtank_tui.files.names import LOG_VARIABLES, PLOT_TYPES, check_names
from quadtank_tui.files.par import ParFileError, parse_par
from quadtank_tui.files.script import ScriptError, parse_script

CORE = Path(__file__).parents[2] / "quadtank_tui" / "core"

REFUSED = [
    ("LOGGING.Variables", "y1 y1", "must be distinct names from t y1 y2 y3 y4 u1 u2 r1 r2 (a name is repeated)"),
    ("LOGGING.Variables", "", "must be distinct names from t y1 y2 y3 y4 u1 u2 r1 r2 (none given)"),
    ("LOGGING.Variables", "y1 q7", "must be distinct names from t y1 y2 y3 y4 u1 u2 r1 r2 (unknown q7)"),
    ("LOGGING.LogFile", "../etc/passwd",
     "must be a plain file name (letters, digits, _ - .; no folders), got '../etc/passwd'"),
    ("LOGGING.LogFile", "a/b", "must be a plain file name (letters, digits, _ - .; no folders), got 'a/b'"),
    ("LOGGING.LogFile", ".hidden", "must be a plain file name (letters, digits, _ - .; no folders), got '.hidden'"),
    ("PLOTS.Lower", "y3", "must be one of u1, u2, u1 u2, y1 ref1, y2 ref2, y1 y2 ref1 ref2, y1 y2 y3 y4; got 'y3'"),
    ("PLOTS.Upper", "u1 u1", "must be one of u1, u2, u1 u2, y1 ref1, y2 ref2, y1 y2 ref1 ref2, y1 y2 y3 y4; "
     "got 'u1 u1'"),
]


@pytest.mark.parametrize("key, value, reason", REFUSED)
def test_check_names_refuses_naming_the_key(key: str, value: str, reason: str) -> None:
    with pytest.raises(ParameterError) as info:
        check_names({key: value})
    assert (info.value.field, info.value.reason) == (key, reason)


def test_check_names_gives_the_canonical_form_and_passes_other_keys() -> None:
    out = check_names({"PLOTS.Lower": " Y1  y2 REF1 ref2 ", "LOGGING.Variables": ["t", "y1"],
                       "LOGGING.LogFile": "run-1.b", "CONTROLLER ONE.K": 3.0})
    assert out == {"PLOTS.Lower": "y1 y2 ref1 ref2", "LOGGING.Variables": ("t", "y1"),
                   "LOGGING.LogFile": "run-1.b", "CONTROLLER ONE.K": 3.0}
    assert PRESET.with_values(out).plots.lower == "y1 y2 ref1 ref2"


@pytest.mark.parametrize("key, value, reason", REFUSED)
def test_a_par_with_a_bad_name_is_refused_with_file_line_and_key(key: str, value: str, reason: str) -> None:
    section, name = key.split(".")
    text = f"SAMPLING TIME\nTSamp 100\n\n{section}\n{name} {value}\n"
    with pytest.raises(ParFileError) as info:
        parse_par(text, name="bad.par")
    assert str(info.value) == f"bad.par, line 5: {key}: {reason}" or (
        value == "" and "malformed line" in str(info.value))  # "Variables" alone is not 'Key value'


def test_a_par_with_loose_plot_spelling_loads_canonical() -> None:
    read = parse_par("PLOTS\nUpper  Y1   REF1\nLower y1 Y2 y3 y4\n", name="p.par")
    assert (read.params.plots.upper, read.params.plots.lower) == ("y1 ref1", "y1 y2 y3 y4")


@pytest.mark.parametrize("key, value, reason", [r for r in REFUSED if r[1]])
def test_a_script_setting_a_bad_name_is_refused(key: str, value: str, reason: str) -> None:
    with pytest.raises(ScriptError) as info:
        parse_script(f'- at: 0\n  set: {{"{key}": "{value}"}}\n', name="exp.yaml")
    assert str(info.value).startswith("exp.yaml") and f"{key}: {reason}" in str(info.value)


def test_the_engine_refuses_a_bad_name_and_changes_nothing(tmp_path: Path) -> None:
    engine = build_engine(clock="manual", params_dir=tmp_path / "params", logs_dir=tmp_path / "logs")
    try:
        _refuses_a_bad_plot_type(engine)
    finally:
        engine.stop()


def _refuses_a_bad_plot_type(engine: Engine) -> None:
    before = engine.snapshot().params
    result = engine.submit(SetParams({"PLOTS.Upper": "y9", "CONTROLLER ONE.K": 9.0})).result()
    assert not result.ok and "PLOTS.Upper: must be one of u1, u2" in result.message
    assert engine.snapshot().params == before
    assert engine.submit(SetParams({"PLOTS.Upper": "Y1 REF1"})).result().ok
    assert engine.snapshot().params.plots.upper == "y1 ref1"


def test_the_core_holds_no_list_of_file_or_screen_names() -> None:
    """The lists live in files.names only: no module of the core defines them."""
    defined: set[str] = set()
    for path in CORE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Assign):
                defined.update(t.id for t in node.targets if isinstance(t, ast.Name))
            elif isinstance(node, ast.FunctionDef):
                defined.add(node.name)
    assert not defined & {"PLOT_TYPES", "LOG_VARIABLES", "check_file_name", "check_variables", "_FILE_NAME"}
    assert LOG_VARIABLES[0] == "t" and "y1 y2 ref1 ref2" in PLOT_TYPES
