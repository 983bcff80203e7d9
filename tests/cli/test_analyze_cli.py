"""`quadtank analyze` prints the published figures (issue 2)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from quadtank_tui.cli import main


def test_analyze_json_nonminphase(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", "--preset", "nonminphase", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) >= {"time_constants", "static_gains", "zeros", "phase", "rga"}
    assert out["time_constants"] == pytest.approx([63.21, 91.40, 39.01, 56.11], abs=0.01)
    assert out["static_gains"][0] == pytest.approx([1.524, 2.451], abs=1e-3)
    assert out["static_gains"][1] == pytest.approx([2.556, 1.597], abs=1e-3)
    assert [z[0] for z in out["zeros"]] == pytest.approx([-0.0562, 0.0128], abs=1e-4)
    assert out["phase"] == "nonminimum"
    assert out["rga"][0] == pytest.approx([-0.636, 1.636], abs=1e-3)


def test_analyze_table_minphase(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", "--preset", "minphase"]) == 0
    out = capsys.readouterr().out
    assert "T1=62.70  T2=90.34  T3=23.89  T4=29.99" in out
    assert "Transmission zeros:     -0.0580, -0.0172" in out
    assert "Phase:                  minimum (gamma1 + gamma2 = 1.30 > 1)" in out


def test_python_dash_m_entry_point() -> None:
    r = subprocess.run(
        [sys.executable, "-m", "quadtank_tui", "analyze", "--preset", "nonminphase", "--json"],
        capture_output=True, text=True, check=True,
    )
    assert json.loads(r.stdout)["phase"] == "nonminimum"


def test_unknown_preset_is_a_clear_usage_error() -> None:
    r = subprocess.run(
        [sys.executable, "-m", "quadtank_tui", "analyze", "--preset", "nope"],
        capture_output=True, text=True,
    )
    assert r.returncode == 2
    assert "invalid choice: 'nope'" in r.stderr
    assert "Traceback" not in r.stderr
