"""`quadtank run`: a headless experiment from the command line."""

from __future__ import annotations

from pathlib import Path

import pytest

from quadtank_tui.cli import main
from quadtank_tui.files.log_reader import read_log

ROOT = Path(__file__).resolve().parents[2]


def test_runs_the_sample_session_and_prints_the_summary(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                        in_params_copy: Path) -> None:
    # the working directory holds a copy of params/ (default.par, minphase.par)
    out = tmp_path / "a4.log"
    code = main(["run", "--par", "minphase", "--script", "params/sample_session.yaml",
                 "--duration", "1200", "--log", str(out), "--seed", "7"])
    text = capsys.readouterr().out
    assert code == 0
    assert "1200 samples, 0 overruns" in text
    assert "   1     -0.00000       5.1 %         53 s" in text
    assert f"{out} (600 rows)" in text
    log = read_log(out)
    assert log.rows == 600 and log.created_text == "Jan 01 00:10:00 2000"


def test_without_a_script_it_logs_the_whole_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plain"
    assert main(["run", "--duration", "30", "--log", str(out)]) == 0
    log = read_log(tmp_path / "plain.log")
    assert log.rows == 300 and log.tsamp == 0.1
    assert "Manual: no loop to measure" in capsys.readouterr().out


@pytest.mark.parametrize("args, message", [
    (["--duration", "0"], "--duration must be a positive number"),
    # issue 41: an OverflowError traceback, and a run of 31,710 years accepted
    (["--duration", "inf"], "--duration inf s would run forever: at most 604800 s (7 days)"),
    (["--duration", "1e12"], "--duration 1e+12 s would run 31,688 years: at most 604800 s (7 days)"),
    (["--duration", "1e12", "--realtime", "--detach"], "--duration 1e+12 s would run 31,688 years"),
    (["--duration", "604801"], "--duration 604801 s would run 7.0 days: at most 604800 s"),
    (["--duration", "10", "--speed", "5000"], "--speed must be 1..1000"),
    (["--duration", "10", "--seed", "-3"], "--seed must be >= 0"),
    (["--duration", "10", "--script", "missing.yaml"], "missing.yaml: no such file"),
    (["--duration", "10", "--par", "missing.par"], "missing.par"),
])
def test_bad_input_is_one_line_and_status_2(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                            args: list[str], message: str) -> None:
    code = main(["run", "--log", str(tmp_path / "x.log"), *args])
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count("\n") == 1 and "Traceback" not in err


def test_a_bad_log_name_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--duration", "1", "--log", str(tmp_path / "bad name.log")]) == 2
    assert "--log" in capsys.readouterr().err
