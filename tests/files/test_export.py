"""Exports: `.mat` holds one column vector per variable plus TSamp; `.csv` a header
row and exact values."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from quadtank_tui.files.export import csv_text, export_log
from quadtank_tui.files.log_reader import parse_log, read_log

GOLDEN = Path(__file__).parent / "golden"


def test_mat_has_one_variable_per_column_and_tsamp(tmp_path: Path) -> None:
    log = read_log(GOLDEN / "thesis.log")
    out = export_log(log, tmp_path / "thesis.mat", "mat")
    m = scipy.io.loadmat(out)
    assert sorted(k for k in m if not k.startswith("__")) == ["TSamp", "u1", "u2", "y1", "y2"]
    for name in log.variables:
        assert m[name].shape == (16, 1)
        np.testing.assert_array_equal(m[name][:, 0], log[name])
    assert m["TSamp"].item() == 1.0


def test_mat_without_tsamp(tmp_path: Path) -> None:
    log = parse_log("% Logged variables: t y1\n0 0.5\n0.1 0.6\n")
    m = scipy.io.loadmat(export_log(log, tmp_path / "x.mat", "mat"))
    assert "TSamp" not in m and m["t"][:, 0].tolist() == [0.0, 0.1]


def test_csv_header_row_and_exact_values(tmp_path: Path) -> None:
    log = read_log(GOLDEN / "thesis.log")
    out = export_log(log, tmp_path / "thesis.csv", "csv")
    lines = out.read_text().splitlines()
    assert lines[0] == "y1,y2,u1,u2"
    assert lines[1] == "0.62207,0.623535,0.3,0.3"
    assert lines[8] == "0.621094,0.624023,0.33,0.3"
    assert len(lines) == 17
    np.testing.assert_array_equal(np.loadtxt(out, delimiter=",", skiprows=1), log.data)
    assert csv_text(parse_log("% Logged variables: y1\n")) == "y1\n"


def test_unknown_format(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="export format must be one of mat, csv, got 'xls'"):
        export_log(read_log(GOLDEN / "thesis.log"), tmp_path / "x.xls", "xls")
    assert os.listdir(tmp_path) == []
