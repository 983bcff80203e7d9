"""Values changed in a .par's text in place: the other lines stay byte for byte."""

from __future__ import annotations

import pytest

from quadtank_tui.files.par import ParFileError
from quadtank_tui.files.par_edit import text_diff, with_par_values

TEXT = "% TANK PAR-file\n% Created on: x\n\nSIMULATION\nTimeConst1 70.000000\nSensor 0.5\n\nPLANT\nKind coupled-cascade\nalpha1 0.0095\n\n"


def test_a_value_is_replaced_where_it_stands_and_a_missing_key_is_added_at_the_section_end() -> None:
    new = with_par_values(TEXT, {"SIMULATION.TimeConst1": "62.703390", "PLANT.alpha2": "0.0098811"})
    assert new == TEXT.replace("TimeConst1 70.000000", "TimeConst1 62.703390").replace(
        "alpha1 0.0095\n", "alpha1 0.0095\nalpha2 0.0098811\n")
    assert text_diff(TEXT, new, "f.par").splitlines()[:2] == ["--- f.par", "+++ f.par (calibrated)"]
    assert text_diff(TEXT, TEXT, "f.par") == ""


def test_crlf_files_keep_their_line_ends() -> None:
    crlf = TEXT.replace("\n", "\r\n")
    assert with_par_values(crlf, {"PLANT.alpha1": "0.0097909"}) == crlf.replace("0.0095", "0.0097909")


def test_a_missing_section_is_refused_naming_the_file() -> None:
    with pytest.raises(ParFileError, match="p.par.*no PLANT section"):
        with_par_values("SIMULATION\nSensor 0.5\n", {"PLANT.alpha1": "0.01"}, "p.par")
