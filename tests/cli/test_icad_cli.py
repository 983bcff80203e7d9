"""`quadtank icad` on the shipped presets; its controllers, typed (the design's model parser) or from the .par (issue 14)."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from quadtank_tui.cli import main
from quadtank_tui.commands.icad_controllers import ExpressionError, controller_from_par, controller_tf, show
from quadtank_tui.core.parameters import PLANT_SETTINGS

PARAMS = Path(__file__).resolve().parents[2] / "params"
TITO = str(PARAMS / "coupled-tito.par")


def icad_json(capsys: pytest.CaptureFixture[str], *args: str) -> dict:
    assert main(["icad", *args, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_murray_smith_figures_from_the_shipped_preset(capsys: pytest.CaptureFixture[str]) -> None:
    """His controllers from the .par (K, Ti = 31, 6.2 and 5.6, 10): ~0.8 and ~0.2 rad/s,
    phase margins above 70 deg, a stable 2x2 loop."""
    out = icad_json(capsys, "--par", TITO)
    assert out["plant"] == "coupled-tito"
    assert out["crossover"] == pytest.approx([0.7817, 0.1565], abs=5e-4)
    assert out["phase_margin_deg"] == pytest.approx([80.3, 75.8], abs=0.1)
    assert out["gain_margin"] == [None, None]
    assert out["gamma_at_0"] == pytest.approx(0.5186, abs=1e-4)
    assert out["min_distance_to_1"] == pytest.approx(0.4814, abs=1e-4)
    assert out["closed_loop_stable"] is True
    assert out["k1"] == {"num": pytest.approx([31.0, 5.0]), "den": [1.0, 0.0]}


def test_expressions_on_the_command_line_agree(capsys: pytest.CaptureFixture[str]) -> None:
    a = icad_json(capsys, "--par", TITO)
    b = icad_json(capsys, "--par", TITO, "--k1", "5*(1+6.2*s)/s", "--k2", "0.56(1 + 10s)/s")
    assert b["crossover"] == pytest.approx(a["crossover"], rel=1e-9)
    assert b["phase_margin_deg"] == pytest.approx(a["phase_margin_deg"], rel=1e-9)


def test_table_output(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["icad", "--par", TITO]) == 0
    text = capsys.readouterr().out
    assert "C1                   0.7817                 80.3           inf" in text
    assert "2x2 closed loop: stable" in text


@pytest.mark.parametrize("args, message", [
    (["--par", str(PARAMS / "coupled-cascade.par")], "ICAD needs a 2x2 loop"),
    (["--par", TITO, "--k1", "5(1+6.2s"], "--k1 '5(1+6.2s': expected ')' to close the '(' at column 2, found the end (column 9)"),
    (["--par", TITO, "--k1", "s^2+1"], "improper"),
    (["--par", TITO, "--k2", "2*x"], "--k2 '2*x': unknown name 'x'"),
    (["--par", TITO, "--k2", "exp(-2*s)*5*(1+6.2*s)/s"], "a dead time exp(-2*s) cannot be used"),
    (["--par", "nope.par"], "no such file"),
])
def test_bad_input_is_one_line(capsys: pytest.CaptureFixture[str], args: list[str], message: str) -> None:
    assert main(["icad", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err


@pytest.mark.parametrize("text, num, den", [
    ("5*(1+6.2*s)/s", [31.0, 5.0], [1.0, 0.0]),
    ("2", [2.0], [1.0]),
    ("-(s+1)/(s^2+2s+1)", [-1.0, -1.0], [1.0, 2.0, 1.0]),
    ("3(1 + 1/(30 s))", [3.0, 0.1], [1.0, 0.0]),
    ("1/(1+.5s)^2", [4.0], [1.0, 4.0, 4.0]),
    ("2e-1*s/(s+1e1)", [0.2, 0.0], [1.0, 10.0]),
])
def test_controller_tf(text: str, num: list[float], den: list[float]) -> None:
    n, d = controller_tf(text)
    np.testing.assert_allclose(n, num, rtol=1e-12)
    np.testing.assert_allclose(d, den, rtol=1e-12)


@pytest.mark.parametrize("text", ["", "1/0", "(s", "s)", "s^x", "2**s", "1/(s-s)", "exp(-s)/s"])
def test_controller_tf_refuses(text: str) -> None:
    with pytest.raises(ExpressionError):
        controller_tf(text)


def test_controller_from_par_is_volts_per_volt() -> None:
    p = PLANT_SETTINGS["coupled-tito"]
    num, den = controller_from_par(p.controllers[0], "PID", 1.0)
    s = 0.4j
    assert np.polyval(num, s) / np.polyval(den, s) == pytest.approx(5 * (1 + 6.2 * s) / s, rel=1e-12)
    num, den = controller_from_par(p.controllers[0], "General", 2.2)  # K s + K/Ti over s
    assert np.polyval(num, s) / np.polyval(den, s) == pytest.approx(2.2 * 5 * (1 + 6.2 * s) / s, rel=1e-9)
    assert show((np.array([31.0, -5.0]), np.array([1.0, 0.0]))) == "(31s - 5)/(1s)"


@pytest.mark.parametrize("name, poles", [
    ("coupled-cascade", [-0.057025, -0.055988]),
    ("desautel-qtp", [-0.07438, -0.06758, -0.05201, -0.03308]),
])
def test_analyze_par_of_another_plant(capsys: pytest.CaptureFixture[str], name: str, poles: list[float]) -> None:
    """`quadtank analyze --par` linearizes the plant the file names."""
    assert main(["analyze", "--par", str(PARAMS / f"{name}.par"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["plant"] == name
    assert [p[0] for p in out["poles"]] == pytest.approx(poles, abs=1e-5)
    if name == "desautel-qtp":
        assert [z[0] for z in out["zeros"]] == pytest.approx([-0.06090, -0.02419], abs=1e-5)
        assert out["phase"] == "minimum"


def test_analyze_table_of_the_two_input_rig(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", "--par", TITO]) == 0
    text = capsys.readouterr().out
    assert "Operating levels (m): H1=0.115  H2=0.071" in text
    assert "RGA at s = 0:" in text


def test_a_par_without_controllers_has_no_crossover_and_no_numpy_warning(
        capsys: pytest.CaptureFixture[str]) -> None:
    """desautel-qtp.par has no PI on either loop (k1 = k2 = 0): both channels are
    zero, so neither has a crossover; numpy's "divide by zero encountered in log"
    (log|C| of C = 0) used to reach the user's terminal."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = icad_json(capsys, "--par", str(PARAMS / "desautel-qtp.par"))
    assert out["crossover"] == [None, None] and out["phase_margin_deg"] == [None, None]
    assert out["gain_margin"] == [None, None]
    assert out["closed_loop_stable"] is True
    assert capsys.readouterr().err == ""
