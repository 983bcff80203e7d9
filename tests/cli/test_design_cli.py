"""`quadtank design`: one model to Kc, Ti, Td and Andersson's figures; the 2x2 check."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from quadtank_tui.cli import main
from quadtank_tui.files.par import read_par

PARAMS = Path(__file__).resolve().parents[2] / "params"
P1 = "1.6592*exp(-2.4*s)/(1.07*s+1)^3"


def test_pi_ms_json_is_andersson_s_row(capsys: pytest.CaptureFixture[str]) -> None:
    """003_... line 475: PI_opt Ms=1.4 on process 1, Kc=0.1464, Ti=2.394, IAE 98.52."""
    assert main(["design", "--model", P1, "--method", "pi-ms", "--ms", "1.4", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["Kc"] == pytest.approx(0.1464, rel=0.01) and out["Ti"] == pytest.approx(2.394, rel=0.01)
    assert out["Td"] == 0.0
    ev = out["evaluation"]
    assert set(ev) >= {"Ms", "phase_margin_deg", "gain_margin", "delay_margin", "crossover",
                       "IAE", "Emax", "u_overshoot"}
    assert ev["Ms"] == pytest.approx(1.40, abs=0.01) and ev["IAE"] == pytest.approx(98.52, rel=0.02)


def test_lambda_evaluated_on_another_model(capsys: pytest.CaptureFixture[str]) -> None:
    """Line 471: lambda 4 on the first-order model, evaluated on the simulation model."""
    assert main(["design", "--model", "1.6637*exp(-3.60*s)/(2.13*s+1)", "--method", "lambda",
                 "--lambda", "4", "--evaluate-on", P1]) == 0
    out = capsys.readouterr().out
    assert "Kc = 0.1685   Ti = 2.13 s" in out
    assert "Ms 1.569" in out and "IAE 77.9" in out


def test_pid_ms_table(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["design", "--model=-0.00651*exp(-2*s)/s", "--method", "pid-ms", "--ms", "1.4"]) == 0
    out = capsys.readouterr().out
    assert "Kc = -32.6" in out and "Td s/(1 + s Td/10) on y" in out and "Ms 1.40" in out


@pytest.mark.parametrize("argv, words", [
    (["--model", "1/(s+1"], "column 7: expected ')'"),
    (["--model", "1/(s-1)", "--method", "lambda"], "pole in the right half-plane"),
    (["--model", P1, "--ms", "0.9"], "Ms must be a number > 1"),
    (["--model", P1, "--write-par", "x.par"], "--write-par needs --par"),
    (["--par", str(PARAMS / "minphase.par"), "--method", "pi-ms", "--sampling", "0", "--no-step"],
     "Ms alone does not bound"),
    # issue 41: 72.8 TiB asked for, a traceback
    (["--par", str(PARAMS / "minphase.par"), "--window", "1e12"],
     "--window must be a positive number of seconds up to 3000 (30000 samples of 0.1 s), got 1e+12"),
    (["--par", str(PARAMS / "minphase.par"), "--window", "inf"], "got inf"),
    (["--par", str(PARAMS / "minphase.par"), "--window", "-5"], "got -5"),
])
def test_bad_input_is_one_message(argv: list[str], words: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["design", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("quadtank: error: ") and words in err and "Traceback" not in err


def test_caret_under_the_column(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["design", "--model", "2*s/(s+1)+exp(-s)"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[1] == "  2*s/(s+1)+exp(-s)" and err[2] == "  " + " " * 9 + "^"


def test_p_minus_2x2_with_step(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["design", "--par", str(PARAMS / "minphase.par")]) == 0
    out = capsys.readouterr().out
    assert "closed loop stable" in out
    assert "sampled at h = 0.1 s" in out  # minphase.par's TSamp
    assert "r1 predicted: overshoot 0.0 %" in out and "r1 simulated: overshoot 0.0 %" in out
    assert "r2 simulated: overshoot" in out and "peak in y1" in out and "WARNING" not in out


def test_p_plus_2x2_writes_a_par_with_k2_negative(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_par = tmp_path / "designed.par"
    assert main(["design", "--par", str(PARAMS / "nonminphase.par"), "--no-step", "--json",
                 "--write-par", str(out_par)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["det_G0"] < 0 and out["stable"]
    assert "no decentralized PI" in out["notes"][0]
    k1, k2 = (loop["Kc"] for loop in out["loops"])
    assert k1 > 0 > k2
    params = read_par(out_par).params
    assert params.get("CONTROLLER ONE.K") == k1 and params.get("CONTROLLER FOUR.K") == k2
    assert params.get("CONTROLLER FOUR.Ti") == out["loops"][1]["Ti"]
    assert params.get("CONTROL.Structure").value == "Decentralized"


def _model_file(path: Path, gains: list) -> Path:
    """A 2x2 of first-order elements K/(62 s + 1); a gain 0 is a null element."""
    path.write_text(json.dumps({"format": "quadtank-model", "version": 1, "method": "oe",
                                "inputs": ["u1", "u2"], "outputs": ["y1", "y2"],
                                "elements": [[{"num": [k], "den": [62.0, 1.0], "delay": 0.0} if k else None
                                              for k in row] for row in gains]}))
    return path


def test_bad_model_file_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    deep = tmp_path / "deep.model.json"
    deep.write_text("[" * 100_000)  # issue 41: a RecursionError traceback
    assert main(["design", "--model-file", str(deep)]) == 2
    assert capsys.readouterr().err == (f"quadtank: error: {deep}: nested deeper than any model file "
                                       "(lists or objects inside each other): not a model file\n")
    missing = tmp_path / "none.model.json"
    not_json = tmp_path / "bad.model.json"
    not_json.write_text("{\n  oops\n")
    half = _model_file(tmp_path / "half.model.json", [[2.6, 0], [1.3, 2.6]])
    whole = _model_file(tmp_path / "whole.model.json", [[2.6, 1.3], [1.3, 2.6]])
    cases = [
        (["--model-file", str(missing)], f"{missing}: no such file"),
        (["--model-file", str(not_json)], f"{not_json}: not JSON (line 2"),
        (["--model-file", str(half)], f"{half}: no element y1/u2 (u2 never moved"),
        (["--model-file", str(whole), "--write-par", "x.par"], "--write-par with --model-file needs --par"),
        (["--model", P1, "--par", str(PARAMS / "minphase.par")], "--model and --par: choose one"),
        ([], "a model is needed"),
        (["--par", str(PARAMS / "coupled-tito.par")],  # Murray-Smith's levels need pump 2 backwards
         "coupled-tito.par: PLANT.Level1/Level2: levels (0.115, 0.071) m need pump voltages (3.22, -0.435) V"),
    ]
    for argv, words in cases:
        assert main(["design", *argv]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and words in err and "Traceback" not in err, (argv, err)


def test_model_file_without_par_designs_and_checks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Lambda = T/5 on 2.6/(62 s + 1): Kc = T/(K lambda) = 5/2.6 = 1.923, Ti = T;
    lambda11(0) = 2.6^2/(2.6^2 - 1.3^2) = 4/3.  No --par: no step on the simulator."""
    whole = _model_file(tmp_path / "whole.model.json", [[2.6, 1.3], [1.3, 2.6]])
    assert main(["design", "--model-file", str(whole)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{whole}: identified model, method lambda")
    assert "lambda11(0) = 1.333" in out and "loop 2 on g22: Kc=1.923, Ti=62 " in out
    assert "closed loop stable" in out and "nonlinear simulator" not in out


def test_design_par_prints_the_par_warnings_on_stderr(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """An unknown key in the .par is kept and said (as run, analyze and icad say it);
    design --par used to drop the warning."""
    par = tmp_path / "mine.par"
    par.write_text((PARAMS / "minphase.par").read_text() + "\nCONTROL\nFoo 1\n")
    assert main(["design", "--par", str(par), "--no-step"]) == 0
    captured = capsys.readouterr()
    assert f"quadtank: warning: {par}, line" in captured.err and "unknown key 'Foo' in CONTROL" in captured.err
    assert "closed loop stable" in captured.out


def test_the_cascade_has_one_loop_y2_from_the_pump(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """One pump: one loop on the lower level, designed on the physical linearization,
    previewed, and written as matrix element 12 (u1 from error 2, the full matrix)."""
    out = tmp_path / "cascade.par"
    assert main(["design", "--par", str(PARAMS / "coupled-cascade.par"), "--sampling", "1",
                 "--write-par", str(out), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    (loop,) = d["loops"]
    assert (loop["output"], loop["input"], loop["element"]) == ("y2", "u1", "CONTROLLER TWO")
    assert "has one pump: one loop is designed, y2 <- u1" in d["notes"][0]
    # G21 = 1.723 / (313.2 s^2 + 35.40 s + 1) at x1 = 15 cm (Desautel's operating point)
    assert loop["model"].startswith("(1.72303)/(313.214*s^2 + 35.3972*s + 1)")
    assert (loop["Kc"], loop["Ti"]) == (pytest.approx(1.109, abs=1e-3), pytest.approx(28.05, abs=0.01))
    (step,) = d["preview"]["steps"]
    assert d["preview"]["warnings"] == [] and step["simulated"]["settling_time"] is not None
    p = read_par(out).params
    assert p.tsamp == 1.0 and p.get("CONTROLLER TWO.K") == loop["Kc"] and p.get("CONTROLLER ONE.K") == 0.0
    assert p.get("CONTROL.Structure").value == "FullMatrix"
