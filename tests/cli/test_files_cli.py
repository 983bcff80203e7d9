"""`quadtank analyze --par`, `quadtank log info`, `quadtank log export`: output on
stdout, one clear line and exit 2 on bad input."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest
import scipy.io

from quadtank_tui.cli import main

ROOT = Path(__file__).parents[2]
THESIS_LOG = ROOT / "tests" / "files" / "golden" / "thesis.log"


def test_analyze_par_uses_the_simulation_section(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", "--par", str(ROOT / "params" / "nonminphase.par"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["linearized_at"] == "levels"
    assert out["phase"] == "nonminimum"
    assert [round(t, 2) for t in out["time_constants"]] == [63.21, 91.4, 39.01, 56.11]


def test_analyze_par_table(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", "--par", str(ROOT / "params" / "default.par")]) == 0
    out = capsys.readouterr().out
    assert "default.par, linearized at its operating levels" in out
    assert "T1=62.70  T2=90.34  T3=23.89  T4=29.99" in out


def test_analyze_par_warns_about_unknown_keys(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "old.par"
    f.write_text("SIMULATION\nValve1 0.4\nValve2 0.3\nColour blue\n")
    assert main(["analyze", "--par", str(f)]) == 0
    captured = capsys.readouterr()
    assert "Phase:                  nonminimum" in captured.out
    assert captured.err == f"quadtank: warning: {f}, line 4: unknown key 'Colour' in SIMULATION (kept, not used)\n"


@pytest.mark.parametrize(
    "argv, message",
    [
        (["analyze", "--par", "missing.par"], "quadtank: error: missing.par: no such file\n"),
        (["analyze", "--par", "PARAMS/default.par", "--at", "steady"],
         "quadtank: error: --at steady needs pump voltages; a .par file gives operating levels only\n"),
        (["log", "info", "missing.log"], "quadtank: error: missing.log: no such file\n"),
        (["log", "info", "PARAMS/default.par"],
         "quadtank: error: PARAMS/default.par, line 1: this is a .par parameter file, not a .log\n"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv: list[str], message: str, capsys: pytest.CaptureFixture[str],
                                          in_params_copy: Path) -> None:
    argv = [a.replace("PARAMS", "params") for a in argv]
    assert main(argv) == 2
    assert capsys.readouterr().err == message.replace("PARAMS", "params")


def test_broken_par_names_line_and_key(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "b.par"
    f.write_text("SIMULATION\nValve1 0.4\nValve2 x\n")
    assert main(["analyze", "--par", str(f)]) == 2
    assert capsys.readouterr().err == f"quadtank: error: {f}, line 3: SIMULATION.Valve2: not a number: 'x'\n"


def test_log_info(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["log", "info", str(THESIS_LOG)]) == 0
    assert capsys.readouterr().out == (
        f"file       {THESIS_LOG}\ncreated    Jun 20 00:30:50 1997\nvariables  y1 y2 u1 u2\n"
        "TSamp      1 s\nrows       16\nduration   16 s\n"
    )


def test_log_export_default_and_explicit_paths(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "data.log"
    src.write_bytes(THESIS_LOG.read_bytes())
    assert main(["log", "export", str(src), "--to", "mat"]) == 0
    assert capsys.readouterr().out == f"{tmp_path / 'data.mat'}\n"
    assert scipy.io.loadmat(tmp_path / "data.mat")["y1"].shape == (16, 1)
    assert main(["log", "export", str(src), "--to", "csv", "--out", str(tmp_path / "x.csv")]) == 0
    assert (tmp_path / "x.csv").read_text().startswith("y1,y2,u1,u2\n0.62207,")


def test_log_export_refuses_to_overwrite_its_source(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "data.log"
    src.write_bytes(THESIS_LOG.read_bytes())
    assert main(["log", "export", str(src), "--to", "csv", "--out", str(src)]) == 2
    assert "the export would overwrite the log itself" in capsys.readouterr().err
    assert src.read_bytes() == THESIS_LOG.read_bytes()


def test_log_export_needs_a_format(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["log", "export", str(THESIS_LOG)])
    assert info.value.code == 2
    assert "the following arguments are required: --to" in capsys.readouterr().err


def test_log_export_choices_are_the_export_formats() -> None:
    """commands/logs.py writes the formats out so the parser does not load scipy.io."""
    from quadtank_tui.commands.logs import EXPORT_FORMATS
    from quadtank_tui.files.export import FORMATS

    assert EXPORT_FORMATS == FORMATS


@pytest.mark.parametrize("to, name", [("csv", "default.par"), ("mat", "default.par"), ("csv", "Preset.PAR")])
def test_log_export_never_writes_a_reserved_parameter_file(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                           to: str, name: str) -> None:
    params = tmp_path / "params"
    params.mkdir()
    (params / "default.par").write_text("SIMULATION\nValve1 0.7\n")
    for force in ([], ["--force"]):
        assert main(["log", "export", str(THESIS_LOG), "--to", to, "--out", str(params / name), *force]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"quadtank: error: {params / name}: '") and "is reserved" in err and err.count("\n") == 1
    assert sorted(os.listdir(params)) == ["default.par"]
    assert (params / "default.par").read_text() == "SIMULATION\nValve1 0.7\n"


def test_log_export_overwrites_only_with_force(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "mine.csv"
    out.write_text("my notes\n")
    assert main(["log", "export", str(THESIS_LOG), "--to", "csv", "--out", str(out)]) == 2
    assert capsys.readouterr().err == f"quadtank: error: {out} exists; give --force to overwrite it\n"
    assert out.read_text() == "my notes\n" and sorted(os.listdir(tmp_path)) == ["mine.csv"]
    assert main(["log", "export", str(THESIS_LOG), "--to", "csv", "--out", str(out), "--force"]) == 0
    assert out.read_text().startswith("y1,y2,u1,u2\n0.62207,")


def test_log_export_to_a_symlink_loop_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Found by benchmarks/hardening.py (hostile paths): --out naming a symlink loop
    raised RuntimeError from Path.resolve(), a traceback; a link to the log itself is
    still recognised as the log."""
    log = tmp_path / "a.log"
    shutil.copy(THESIS_LOG, log)
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    assert main(["log", "export", str(log), "--to", "csv", "--out", str(loop)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("quadtank: error: ") and "loop" in err and err.count("\n") == 1, err
    link = tmp_path / "link.log"
    link.symlink_to(log)
    assert main(["log", "export", str(log), "--to", "csv", "--out", str(link), "--force"]) == 2
    assert "the export would overwrite the log itself" in capsys.readouterr().err
