"""`quadtank identify`: the report, --save, and bad input (one line, status 2)."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

import numpy as np
import pytest

from quadtank_tui.cli import main
from quadtank_tui.core.identify.sampling import simulate
from quadtank_tui.files.log_writer import format_header, format_row
from quadtank_tui.files.model import read_model


def write_log(path: Path, columns: dict[str, np.ndarray], tsamp: float = 1.0) -> Path:
    names = list(columns)
    rows = np.column_stack([columns[n] for n in names])
    path.write_text(format_header(names, tsamp, datetime(2000, 1, 1)) + "".join(format_row(r) for r in rows))
    return path


def simo(path: Path, rows: int = 1200) -> Path:
    """u1 steps (two steps) into G11 = 2.6/(1 + 62 s), u2 constant."""
    u1 = np.full(rows, 0.30)
    u1[100:], u1[700:] = 0.33, 0.31
    y1 = 0.61 + simulate(np.array([2.6]), np.array([62.0, 1.0]), 1.0, u1 - 0.30)
    y2 = 0.64 + simulate(np.array([1.4]), np.array([2700.0, 120.0, 1.0]), 1.0, u1 - 0.30)
    return write_log(path, {"y1": y1, "y2": y2, "u1": u1, "u2": np.full(rows, 0.30)})


def test_report_and_save(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = simo(tmp_path / "steps.log")
    assert main(["identify", str(log), "--save"]) == 0
    out = capsys.readouterr().out
    assert "G11  2.6/(1+62s)" in out
    assert "Physical model: P- (minimum phase)" in out
    assert f"Model saved to {tmp_path / 'steps.model.json'}" in out
    model = read_model(tmp_path / "steps.model.json")
    assert model.inputs == ("u1",) and model.outputs == ("y1", "y2") and model.method == "oe"
    g11 = model.element("y1", "u1")
    assert g11 is not None and g11.static_gain == pytest.approx(2.6, rel=1e-4)
    assert model.operating_point["u1"] == pytest.approx(0.30)


def test_manual_starting_values(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = simo(tmp_path / "steps.log")
    assert main(["identify", str(log), "--outputs", "y2", "--start", "T=20,100", "L=0"]) == 0
    assert "G21  1.4/(1+30s)(1+90s)" in capsys.readouterr().out
    assert main(["identify", str(log), "--method", "step", "--outputs", "y1", "--n", "1",
                 "--start", "T=40", "L=1"]) == 0
    assert "K=2.6  T=62  n=1" in capsys.readouterr().out


def test_par_chooses_the_physical_model(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = simo(tmp_path / "steps.log")
    assert main(["identify", str(log), "--par", "nonminphase", "--outputs", "y1"]) == 0
    assert "Physical model: P+ (nonminimum phase), linearized" in capsys.readouterr().out


def test_another_plant_is_not_compared_with_four_tanks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The cascade's .par: no physical comparison (its SIMULATION section's four tanks
    are not the plant in use), said on stderr (issue 23)."""
    log = simo(tmp_path / "steps.log")
    par = Path(__file__).resolve().parents[2] / "params" / "coupled-cascade.par"
    assert main(["identify", str(log), "--par", str(par), "--outputs", "y1"]) == 0
    out, err = capsys.readouterr()
    assert "Physical model" not in out and "G11  2.6/(1+62s)" in out
    assert "no physical comparison" in err and "coupled tanks, cascade" in err


def test_step_method_prints_the_structures_parameters(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = simo(tmp_path / "steps.log")
    assert main(["identify", str(log), "--method", "step", "--outputs", "y1", "--n", "1"]) == 0
    out = capsys.readouterr().out
    assert "G11  [1] K/(sT+1)^n e^-sL: K=2.6  T=62  n=1  L=" in out  # L ~ 1e-5 (6-decimal rows)
    assert "loss " in out


@pytest.mark.parametrize("make, args, message", [
    (None, [], "no such file"),
    ("const", [], "no input moves (u1 and u2 are constant)"),
    ("short", [], "too few rows to identify from: 20"),
    ("simo", ["--outputs", "y3"], "no column 'y3'"),
    ("simo", ["--inputs", "u2"], "u2 is constant in"),
    ("two-simo", ["--method", "n4sid"], "n4sid needs a log in which u1 and u2 all move (a MIMO experiment)"),
    ("ramp", ["--method", "step"], "no step found in the input"),
    ("mimo", ["--method", "arx"], "u1 and u2 both move; a per-element fit needs one moving input per log"),
    ("simo", ["--validate", "1.5"], "--validate must be a fraction in [0, 1)"),
    ("notsamp", [], "no TSamp in the header"),
    ("simo", ["--par", "missing.par"], "missing.par: no such file"),
    ("simo", ["--start", "K=3"], "--start takes T=VALUE and L=VALUE, got 'K=3'"),
    ("simo", ["--start", "T=abc"], "--start T: not a number in 'abc'"),
    ("simo", ["--start", "T=30,90", "--outputs", "y1"], "starting T needs 1 time constant(s) > 0 s, one per pole"),
])
def test_bad_input_is_one_line_and_status_2(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                            make: str | None, args: list[str], message: str) -> None:
    path = tmp_path / "x.log"
    n = 400
    if make == "simo":
        simo(path)
    elif make == "two-simo":
        simo(path)
        text = (tmp_path / "x.log").read_text().replace("y1 y2 u1 u2", "y2 y1 u2 u1")
        (tmp_path / "x2.log").write_text(text)
        args = [str(tmp_path / "x2.log"), *args]
    elif make == "const":
        write_log(path, {"y1": np.full(n, 0.6), "y2": np.full(n, 0.6), "u1": np.full(n, 0.3), "u2": np.full(n, 0.3)})
    elif make == "short":
        write_log(path, {"y1": np.arange(20.0), "u1": np.arange(20.0)})
    elif make == "ramp":
        write_log(path, {"y1": np.linspace(0, 1, n), "u1": np.linspace(0, 1, n)})
    elif make == "mimo":
        rng = np.random.default_rng(1)
        write_log(path, {"y1": rng.normal(size=n), "u1": rng.normal(size=n), "u2": rng.normal(size=n)})
    elif make == "notsamp":
        path.write_text("% TANK LOG-file\n% Created on: Jan 01 00:00:00 2000\n% Logged variables: y1 u1\n\n"
                        + "".join(f"{i % 7}  {i % 3}\n" for i in range(100)))
    assert main(["identify", str(path), *args]) == 2
    err = capsys.readouterr().err
    assert message in err, err
    assert "Traceback" not in err
    assert [line for line in err.splitlines() if not line.startswith("quadtank: warning")] == [
        next(line for line in err.splitlines() if "error" in line)]
