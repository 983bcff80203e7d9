"""`quadtank run --inputs-from LOG`: a log's pump signals drive the simulator of a
`.par` open loop, into a log whose rows line up with it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from quadtank_tui.cli import main
from quadtank_tui.files.log_reader import read_log

#: Manual mode, a PRBS on pump 1 from the operating point, every sensor logged from t = 0.
SCRIPT = """\
- at: 0
  mode: Manual
- at: 0
  set:
    "SAMPLING TIME.TSamp": 1000
    "REFERENCE ONE.Wave": PRBS
    "REFERENCE ONE.Mean": 0.300
    "REFERENCE ONE.Amplitude": 0.05
    "REFERENCE ONE.Period": 20
    "REFERENCE ONE.Seed": 1
    "REFERENCE ONE.On": 1
    "LOGGING.Variables": y1 y2 u1 u2 y3 y4
- at: 0
  state: Run
- at: 0
  log: on
"""


@pytest.fixture()
def rig_log(in_params_copy: Path) -> Path:
    """A logged simulator run of P- (the 'rig'), 150 rows."""
    Path("prbs.yaml").write_text(SCRIPT)
    assert main(["run", "--par", "minphase", "--script", "prbs.yaml", "--duration", "150", "--log", "rig.log"]) == 0
    return in_params_copy / "rig.log"


def test_a_logged_simulator_run_comes_back_exactly(rig_log: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["run", "--par", "minphase", "--inputs-from", str(rig_log), "--log", "twin.log"]) == 0
    assert "twin.log (150 rows)" in capsys.readouterr().out
    assert Path("twin.log").read_bytes() == rig_log.read_bytes()
    rig = read_log(rig_log)
    assert np.ptp(rig["u1"]) == pytest.approx(0.1) and np.ptp(rig["y4"]) > 0.005  # something happened


def test_another_par_gives_another_twin_that_log_compare_reads(rig_log: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--par", "nonminphase", "--inputs-from", str(rig_log), "--log", "plus.log"]) == 0
    rig, twin = read_log(rig_log), read_log("plus.log")
    assert twin.variables == rig.variables and twin.rows == rig.rows and twin.tsamp == rig.tsamp
    assert np.array_equal(twin["u1"], rig["u1"]) and np.array_equal(twin["u2"], rig["u2"])
    assert twin.data[0].tolist() == rig.data[0].tolist()  # the same levels to start from
    assert np.abs(twin["y1"] - rig["y1"]).max() > 0.005  # P+ sends less of pump 1 to tank 1
    assert main(["log", "compare", str(rig_log), "plus.log"]) == 0


@pytest.mark.parametrize(("args", "message"), [
    (["--script", "prbs.yaml"], "--inputs-from replays a log on the simulator, open loop: --script does not apply"),
    (["--log", "rig.log"], "--log rig.log: that is the log being replayed"),
    (["--log", "/dev/null"], "--log /dev/null: not a regular file (a device, a FIFO or a socket)"),
    (["--log", "nowhere/x.log"], "--log nowhere/x.log: the folder nowhere does not exist"),
    (["--par", "minphase"], "rig.log: no column u1 (pump v1 of the quadtank)"),
])
def test_bad_input_is_one_line_and_status_2(rig_log: Path, capsys: pytest.CaptureFixture[str],
                                            args: list[str], message: str) -> None:
    text = rig_log.read_text()
    if "--par" in args:
        rig_log.write_text(text.replace("y1 y2 u1 u2 y3 y4", "y1 y2 ref1 u2 y3 y4"))
    options = {"--log": "out.log", **dict(zip(args[::2], args[1::2]))}
    capsys.readouterr()
    assert main(["run", "--inputs-from", str(rig_log), *(x for kv in options.items() for x in kv)]) == 2
    err = capsys.readouterr().err
    assert message in err, err
    assert [ln for ln in err.splitlines() if not ln.startswith("quadtank: warning")] == [f"quadtank: error: {err.split('error: ')[1].strip()}"]
    assert not Path("out.log").exists()


#: The same run as a script event: TSamp first (the log's), then the log's inputs.
REPLAY = """\
- at: 0
  set:
    "SAMPLING TIME.TSamp": 1000
    "LOGGING.Variables": y1 y2 u1 u2 y3 y4
- at: 0
  inputs_from: rig.log
- at: 0
  state: Run
- at: 0
  log: on
"""


def test_the_script_event_reproduces_a_logged_simulator_run_exactly(rig_log: Path) -> None:
    """`inputs_from` in a script drives the engine's own loop (Manual, the waves off,
    each row's u1 u2 as the references' means before its sample): the rig's 150 rows
    come back byte for byte, data and header (the virtual clock's start)."""
    Path("replay.yaml").write_text(REPLAY)
    assert main(["run", "--par", "minphase", "--script", "replay.yaml", "--duration", "150",
                 "--log", "again.log"]) == 0
    assert Path("again.log").read_bytes() == rig_log.read_bytes()


@pytest.mark.parametrize(("script", "message"), [
    (REPLAY.replace('"SAMPLING TIME.TSamp": 1000', '"SAMPLING TIME.TSamp": 500'),
     "replay.yaml, event 2 (line 5): inputs_from rig.log: TSamp 1 s, the loop samples every 0.5 s"),
    (REPLAY.replace("inputs_from: rig.log", "inputs_from: none.log"), "replay.yaml, event 2 (line 5): "
     "inputs_from none.log: "),
    (REPLAY.replace("inputs_from: rig.log", "inputs_from: [1]"),
     "replay.yaml, event 2 (line 5): inputs_from needs the path of a log, got [1]"),
])
def test_a_log_that_cannot_drive_the_loop_is_one_line(rig_log: Path, capsys: pytest.CaptureFixture[str],
                                                       script: str, message: str) -> None:
    Path("replay.yaml").write_text(script)
    capsys.readouterr()
    assert main(["run", "--par", "minphase", "--script", "replay.yaml", "--duration", "150",
                 "--log", "again.log"]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
