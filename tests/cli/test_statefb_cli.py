"""`quadtank statefb` prints the design a .par file asks for (issue 15)."""

from __future__ import annotations

import json
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest

from quadtank_tui.cli import main
from quadtank_tui.core.parameters import PRESET
from quadtank_tui.core.controllers.statefb.placement import augment, bessel_poles, robustness
from quadtank_tui.files.par import write_par


def _json(capsys: pytest.CaptureFixture[str], *argv: str) -> dict:
    assert main(["statefb", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_json_has_the_design_and_it_is_consistent(capsys: pytest.CaptureFixture[str]) -> None:
    out = _json(capsys)
    assert set(out) >= {"Phi", "Gamma", "poles", "L1", "L2", "delta"}
    Phi, Gamma = np.array(out["Phi"]), np.array(out["Gamma"])
    L = np.hstack([out["L1"], out["L2"]])
    Phi_d, Gamma_d = augment(Phi, Gamma, np.eye(2, 4))
    placed = np.sort_complex(np.linalg.eigvals(Phi_d - Gamma_d @ L))
    poles = np.sort_complex(np.array([complex(re, im) for re, im in out["poles"]]))
    assert np.abs(placed - poles).max() < 1e-9
    z_from_s = np.sort_complex(np.exp(np.array([complex(*p) for p in out["poles_s"]]) * 0.1))
    assert np.abs(z_from_s - poles).max() < 1e-9
    assert out["delta"] == pytest.approx(robustness(Phi, Gamma, np.eye(2, 4), np.array(out["L1"]),
                                                    np.array(out["L2"])))
    # "zeros": the P- plant's two slow zeros at its steady state are among the s-poles
    assert sorted(re for re, im in out["poles_s"] if im == 0)[-2:] == pytest.approx([-0.0598, -0.0174], abs=1e-4)


def test_ts_and_sampling_override_the_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    par = write_par(tmp_path / "sf.par", PRESET.with_values({"STATE FEEDBACK.Poles": "none"}))
    out = _json(capsys, "--par", str(par), "--ts", "120", "--sampling", "0.5")
    assert out["sampling_time"] == 0.5 and out["poles_setting"] == "none"
    s = np.sort_complex(np.array([complex(*p) for p in out["poles_s"]]))
    assert np.abs(s - np.sort_complex(bessel_poles(6, 120.0))).max() < 1e-12
    assert np.array(out["Phi"])[0, 0] == pytest.approx(np.exp(-0.5 / 62.70339), rel=1e-4)


def test_the_table(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["statefb"]) == 0
    text = capsys.readouterr().out
    assert text.startswith("State-feedback design: built-in preset\n"
                           "linearized at h = (12.400, 12.700, 1.592, 1.455) cm, u_e = (3.0486, 2.9612) V\n")
    for head in ("Phi =", "Gamma =", "poles (s, rad/s) =", "poles (z, placed) =", "L1 =", "L2 =", "delta = "):
        assert f"\n{head}" in text


@pytest.mark.parametrize(("argv", "message"), [
    (["--ts", "0.1"], "quadtank: error: --ts: must be >= 1, got 0.1 s"),
    (["--sampling", "0.01"], "quadtank: error: --sampling: 0.01 s is outside 0.05..10 s"),
    (["--par", "nope.par"], "quadtank: error: nope.par: no such file"),
])
def test_bad_input_is_one_line(capsys: pytest.CaptureFixture[str], argv: list[str], message: str) -> None:
    assert main(["statefb", *argv]) == 2
    assert capsys.readouterr().err.strip() == message


def test_a_file_whose_design_fails_names_the_file_and_key(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    par = write_par(tmp_path / "bad.par", PRESET.with_values({"STATE FEEDBACK.Level1": 2.0,
                                                              "STATE FEEDBACK.Level2": 15.0}),
                    created=datetime(2026, 11, 22))
    assert main(["statefb", "--par", str(par)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"quadtank: error: {par}: STATE FEEDBACK.Level1: cannot linearize there") and "backwards" in err


def test_the_plant_in_use_is_designed_desautels_ctp(capsys: pytest.CaptureFixture[str]) -> None:
    """The cascade's PLANT section, not the SIMULATION section's four tanks (issue 23):
    Desautel's CTP at Ts = 20 s, L_d = [2.1179, 9.9757, 0.13191], two states at x1 = 15 cm."""
    root = Path(__file__).resolve().parents[2]
    d = _json(capsys, "--par", str(root / "params" / "coupled-cascade.par"), "--ts", "20")
    np.testing.assert_allclose([*d["L1"][0], *d["L2"][0]], [2.1179, 9.9757, 0.13191], rtol=5e-5)
    assert d["x_e"] == pytest.approx([15.0, 14.727394], abs=1e-6)


def test_parameters_have_no_ambiguous_plant() -> None:
    """One name for the plant in use; the quadruple tank's constants say so."""
    assert not hasattr(PRESET, "plant")
    assert PRESET.process_plant().values()["a1"] == PRESET.quadtank_constants().a1
