"""Model files: what identification writes and design reads (the formats docs/identification.md states)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.files.model import ModelFile, ModelFileError, model_path, read_model, write_model

MODEL = ModelFile(
    elements=((DelayTF((2.59,), (62.2, 1.0)), DelayTF((1.49,), (1431.0, 85.1, 1.0), 2.0)),
              (None, DelayTF((2.85,), (90.7, 1.0)))),
    inputs=("u1", "u2"), outputs=("y1", "y2"), method="oe",
    logs=("logs/pminus-u1.log",), sampling_time=1.0,
    operating_point={"u1": 0.3, "u2": 0.3, "y1": 0.613, "y2": 0.639},
    fit_percent={"y1": 99.4, "y2": 99.5},
    extra={"phase": "minimum"},
)


def test_round_trip(tmp_path: Path) -> None:
    path = write_model(tmp_path / "m.model.json", MODEL)
    back = read_model(path)
    assert back == MODEL
    assert back.element("y1", "u2") == DelayTF((1.49,), (1431.0, 85.1, 1.0), 2.0)
    data = json.loads(path.read_text())
    assert data["format"] == "quadtank-model" and data["version"] == 1
    assert data["elements"][1][0] is None
    assert data["elements"][0][0] == {"num": [2.59], "den": [62.2, 1.0], "delay": 0.0}


def test_path_next_to_the_log() -> None:
    assert model_path("logs/pminus-u1.log") == Path("logs/pminus-u1.model.json")


@pytest.mark.parametrize("text,reason", [
    ("not json", "not JSON (line 1"),
    ('{"format": "other"}', "not a model file"),
    ('{"format": "quadtank-model", "version": 9}', "version 9"),
    ('{"format": "quadtank-model", "version": 1, "inputs": ["u1"], "outputs": ["y1"], "elements": [[]]}',
     "elements must be 1 rows of 1"),
    ('{"format": "quadtank-model", "version": 1, "inputs": ["u1"], "outputs": ["y1"],'
     ' "elements": [[{"num": [1, 2, 3], "den": [1, 1]}]]}', "elements[0][0]: improper model"),
    ('{"format": "quadtank-model", "version": 1, "inputs": ["u1"], "outputs": ["y1"],'
     ' "elements": [[{"num": [1], "den": [1, 1], "delay": -1}]]}', "elements[0][0]: the delay"),
    ('{"format": "quadtank-model", "version": 1, "inputs": [], "outputs": ["y1"], "elements": []}',
     "inputs must be"),
    # numbers no float holds (OverflowError, a traceback) and JSON's NaN/Infinity (accepted)
    ('{"format": "quadtank-model", "version": 1, "inputs": ["u1"], "outputs": ["y1"],'
     ' "elements": [[{"num": [1' + "0" * 400 + '], "den": [1, 1]}]]}', "lists of finite numbers"),
    ('{"format": "quadtank-model", "version": 1, "inputs": ["u1"], "outputs": ["y1"],'
     ' "elements": [[{"num": [1], "den": [NaN, 1]}]]}', "lists of finite numbers"),
    ('{"format": "quadtank-model", "version": 1, "inputs": ["u1"], "outputs": ["y1"],'
     ' "elements": [[{"num": [1], "den": [1, 1], "delay": Infinity}]]}', "delay must be a finite number"),
    ('{"format": "quadtank-model", "version": 1, "inputs": ["u1"], "outputs": ["y1"],'
     ' "elements": [[{"num": [1], "den": [1, 1]}]], "operating_point": {"u1": 1' + "0" * 400 + '}}',
     "operating_point.u1 must be a finite number"),
    ('{"format": "quadtank-model", "version": 1, "inputs": ["u1"], "outputs": ["y1"],'
     ' "elements": [[{"num": [1], "den": [1, 1]}]], "sampling_time": Infinity}', "sampling_time must be"),
])
def test_bad_files_are_one_clear_line(tmp_path: Path, text: str, reason: str) -> None:
    p = tmp_path / "bad.model.json"
    p.write_text(text)
    with pytest.raises(ModelFileError) as err:
        read_model(p)
    assert str(err.value).startswith(f"{p}: ")
    assert reason in str(err.value)
    assert "\n" not in str(err.value)


def _model_text(element: str, extra: str = "") -> str:
    return ('{"format": "quadtank-model", "version": 1, "inputs": ["u1"], "outputs": ["y1"], '
            f'"elements": [[{element}]]{extra}}}')


@pytest.mark.parametrize("text,reason", [
    ("[" * 100_000, "nested deeper than any model file"),
    (_model_text('{"num": [1], "den": [1, 1]}', ', "notes": ' + "[" * 100_000 + "]" * 100_000),
     "nested deeper than any model file"),
    (_model_text('{"num": [1], "den": [' + ", ".join(["1"] * 5000) + "]}"),
     "elements[0][0]: a polynomial of degree 4999: at most 20 in a model file (21 coefficients)"),
    (_model_text('{"num": [' + ", ".join(["1"] * 22) + '], "den": [1, 1]}'),
     "elements[0][0]: a polynomial of degree 21: at most 20"),
], ids=["nested", "nested inside a valid model", "5000 coefficients", "numerator of degree 21"])
def test_deep_and_long_files_are_refused_at_once(tmp_path: Path, text: str, reason: str) -> None:
    """100,000 nested [ was a RecursionError traceback; a denominator of 5,000
    coefficients took design 77 s and 504 MB."""
    path = tmp_path / "hostile.model.json"
    path.write_text(text)
    with pytest.raises(ModelFileError) as err:
        read_model(path)
    assert str(err.value) == f"{path}: {reason}" or str(err.value).startswith(f"{path}: {reason}")


def test_degree_twenty_is_read(tmp_path: Path) -> None:
    path = tmp_path / "m.model.json"
    path.write_text(_model_text('{"num": [1], "den": [' + ", ".join(["1"] * 21) + "]}"))
    g = read_model(path).elements[0][0]
    assert g is not None and len(g.den) == 21


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ModelFileError, match="no such file"):
        read_model(tmp_path / "none.model.json")
