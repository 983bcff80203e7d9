"""`quadtank run` with a script that selects the MPC (issue 26): the `.par` keys a
script sets reach the loop, which runs the MPC on the simulator in virtual time."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from quadtank_tui.cli import main
from quadtank_tui.files.log_reader import read_log

SCRIPT = """\
- at: 0
  set:
    "SAMPLING TIME.TSamp": 1000
    "CONTROL.Type": MPC
    "MPC.Horizon": 20
    "MPC.RateWeight": 0.1
    "REFERENCE ONE.On": 0
    "REFERENCE TWO.On": 0
- at: 0
  state: Run
- at: 100
  mode: Automatic
- at: 100
  log: on
- at: 110
  step: {"REFERENCE ONE.Mean": 0.05}
"""


def test_a_script_selects_mpc_and_it_tracks_a_step_bumplessly(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    script = tmp_path / "mpc.yaml"
    script.write_text(SCRIPT)
    out = tmp_path / "mpc.log"
    assert main(["run", "--script", str(script), "--duration", "400", "--log", str(out), "--seed", "7"]) == 0
    text = capsys.readouterr().out
    assert "400 samples, 0 overruns" in text
    assert "   1     +0.00000" in text and "   2     -0.00000" in text  # offset-free on both loops
    log = read_log(out)
    y1, u = log["y1"], np.column_stack([log["u1"], log["u2"]])
    assert log.rows == 300 and np.all((u >= 0.0) & (u <= 1.0))
    assert np.abs(u[0] - 0.3).max() < 0.02  # Manual at 0.30 -> MPC in Automatic: no bump
    assert y1[-1] == pytest.approx(y1[0] + 0.05, abs=1e-3)  # the +0.05 step tracked
    assert u[10:20, 0].max() > 0.4  # and the MPC acted on it
