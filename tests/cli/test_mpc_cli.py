"""`quadtank mpc` prints the MPC design of a .par file's plant and compares it with
the file's PI on the nonlinear simulator (issue 26)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from quadtank_tui.cli import main

PARAMS = Path(__file__).resolve().parents[2] / "params"
FAST = ["--sampling", "5", "--horizon", "12", "--phase", "150"]


def _json(capsys: pytest.CaptureFixture[str], *argv: str) -> dict:
    assert main(["mpc", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_design_and_comparison_at_p_minus(capsys: pytest.CaptureFixture[str]) -> None:
    out = _json(capsys, "--par", str(PARAMS / "minphase.par"), *FAST)
    d, c = out["design"], out["comparison"]
    assert d["plant"] == "quadtank" and d["horizon"] == 12 and d["sampling_time"] == 5.0
    assert d["x_e"][:2] == pytest.approx([12.4, 12.7])
    assert np.array(d["K"]).shape == (2, 4)
    z = np.array([complex(*p) for p in d["poles_z"]])
    s = np.array([complex(*p) for p in d["poles_s"]])
    assert np.all(np.abs(z) < 1) and np.allclose(np.sort_complex(np.exp(s * 5.0)), np.sort_complex(z))
    # cheap control puts two poles on the plant's zeros (P-: -0.0598, -0.0174 rad/s)
    assert sorted(p.real for p in s)[-2:] == pytest.approx([-0.0598, -0.0174], abs=2e-3)
    mpc, pi = c["MPC"], c["PI"]
    assert mpc["faults"] == 0 and mpc["violations"] == 0
    for loop in range(2):
        assert mpc["iae"][loop] < 0.8 * pi["iae"][loop]
    assert 0 < mpc["p50_ms"] <= mpc["p99_ms"] and pi["p50_ms"] is None  # strict JSON: no NaN


def test_text_output_and_a_plant_without_pi(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["mpc", "--par", str(PARAMS / "coupled-cascade.par"), *FAST]) == 0
    out = capsys.readouterr().out
    assert "MPC design:" in out and "(coupled-cascade)" in out and "closed-loop poles (z)" in out
    assert "PI   none: the coupled-cascade plant is not wired as two loops" in out
    mpc_row = next(line for line in out.splitlines() if line.startswith("MPC  "))
    assert len(mpc_row.split()) == 1 + 1 + 1 + 1 + 3 + 2  # one loop: IAE, leak, OS; limit viol fail; p50 p99


def test_the_two_input_rig_says_where_it_linearized(capsys: pytest.CaptureFixture[str]) -> None:
    out = _json(capsys, "--par", str(PARAMS / "coupled-tito.par"), "--no-compare")
    assert "linearized at the nearest steady state" in out["design"]["note"]
    assert out["design"]["u_e"][1] == pytest.approx(0.0, abs=1e-9)
    assert "comparison" not in out


@pytest.mark.parametrize("argv, message", [
    (["--horizon", "0"], "--horizon: must be a whole number in 1..1000, got 0"),
    (["--sampling", "0.001"], "--sampling: 0.001 s is outside 0.05..10 s"),
    (["--phase", "1"], "--phase: 1 s is outside 10..100000 s"),
    (["--par", "no-such.par"], "no-such.par"),
])
def test_bad_input_is_one_line_and_exit_2(capsys: pytest.CaptureFixture[str], argv: list[str], message: str) -> None:
    assert main(["mpc", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("quadtank: error: ") and message in err[0]


def test_a_file_whose_type_is_mpc_is_compared_with_its_pid_settings(capsys: pytest.CaptureFixture[str],
                                                                   tmp_path: Path) -> None:
    """CONTROL.Type MPC round-trips through a .par file; the comparison uses the
    file's PID settings (the matrix cannot be of family MPC)."""
    from quadtank_tui.core.controllers.matrix import Family
    from quadtank_tui.files.par import read_par, write_par

    src = read_par(PARAMS / "minphase.par").params.with_values({"CONTROL.Type": "MPC", "MPC.Horizon": 12})
    path = write_par(tmp_path / "mpc.par", src)
    back = read_par(path).params
    assert back.control.family is Family.MPC and back.mpc == src.mpc
    out = _json(capsys, "--par", str(path), "--sampling", "5", "--phase", "150")
    assert out["design"]["horizon"] == 12 and out["comparison"]["PI"] is not None
