"""The comparison table: nine candidates, each designed and evaluated, or its reason."""

from __future__ import annotations

import pytest

from quadtank_tui.core.design.expr import parse_model
from quadtank_tui.core.design.table import candidates, format_table


def test_nine_candidates_on_process_4() -> None:
    rows = candidates(parse_model("-0.00651*exp(-2*s)/s"))
    assert [(r.method, r.parameter) for r in rows] == [
        ("lambda", 4.0), ("lambda", 8.0), ("lambda", 16.0),
        ("pi-ms", 1.6), ("pi-ms", 1.4), ("pi-ms", 1.2),
        ("pid-ms", 1.6), ("pid-ms", 1.4), ("pid-ms", 1.2)]
    for r in rows[3:]:
        assert r.evaluation is not None and r.evaluation.Ms == pytest.approx(r.parameter, abs=0.01)
    # the PI row at Ms 1.4 is Andersson's line 586 (Kc -21.7, Ti 13.5, IAE 6.93)
    pi = rows[4]
    assert pi.controller is not None and pi.evaluation is not None
    assert pi.controller.Kc == pytest.approx(-21.7, rel=0.01)
    assert pi.evaluation.IAE == pytest.approx(6.93, rel=0.02)
    text = format_table(rows)
    assert text.splitlines()[0].split() == ["candidate", "Kc", "Ti", "Td", "IAE", "Emax", "u_os",
                                            "phi_m", "Lm", "Am", "Ms"]
    assert len(text.splitlines()) == 10


def test_a_row_that_cannot_be_designed_says_why() -> None:
    rows = candidates(parse_model("exp(-s)/((s-0.1)*(2*s+1))"), ms_values=(1.4,))
    assert rows[0].method == "lambda" and "right half-plane" in (rows[0].error or "")
    assert all("right half-plane" in (r.error or "") for r in rows)
    assert format_table(rows).count("right half-plane") == 3
