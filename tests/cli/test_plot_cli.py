"""`quadtank plot`, `identify --figure`, `design --figure`: files written, bad input
one line and exit 2 with nothing written, matplotlib never loaded by the TUI's start."""

from __future__ import annotations

import subprocess
import sys
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest

from quadtank_tui.cli import main
from quadtank_tui.commands import plot as plot_command
from quadtank_tui.files.log_writer import format_header, format_row

ROOT = Path(__file__).resolve().parents[2]


def write_log(path: Path, names: tuple[str, ...] = ("t", "y1", "r1", "u1"), tau: float = 20.0) -> Path:
    t = np.arange(300.0)
    r1 = np.where(t >= 10, 0.7, 0.6)
    y1 = 0.6 + 0.1 * (1 - np.exp(-np.maximum(t - 10, 0) / tau))
    cols = {"t": t, "y1": y1, "r1": r1, "u1": 0.3 + 0 * t}
    rows = np.column_stack([cols[n] for n in names])
    path.write_text(format_header(list(names), 1.0, datetime(2000, 1, 1)) + "".join(format_row(r) for r in rows))
    return path


def test_the_choices_agree_with_the_figures_module() -> None:
    from quadtank_tui.files.figures import runs

    assert plot_command.UNITS == runs.UNITS and plot_command.ALIGNS == runs.ALIGNS


def test_two_logs_make_one_svg_with_both_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a, b = write_log(tmp_path / "a.log"), write_log(tmp_path / "b.log", tau=40.0)
    out = tmp_path / "ab.svg"
    assert main(["plot", str(a), str(b), "--out", str(out), "--align", "step", "--units", "V"]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {out}"
    svg = out.read_text()
    for gid in ("a.log:y1", "a.log:r1", "b.log:y1", "b.log:r1"):
        assert f'id="{gid}"' in svg
    assert "<!-- level (V) -->" in svg and "<!-- a.log y1: rise 44 s, overshoot 0.0 %" in svg


@pytest.mark.parametrize("args, message", [
    (["--out", "x.jpg"], "x.jpg: a figure is written as .png, .svg or .pdf (by its suffix), not .jpg"),
    (["--out", "x.png", "--vars", "y1,y3"], "a.log: no column y3 (logged: t y1 r1 u1)"),
    (["--out", "x.png", "--vars", ","], "--vars: no variable named (give e.g. y1,r1)"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch,
                                          args: list[str], message: str) -> None:
    monkeypatch.chdir(tmp_path)
    write_log(tmp_path / "a.log")
    assert main(["plot", "a.log", *args]) == 2
    err = capsys.readouterr().err
    assert err == f"quadtank: error: {message}\n"
    assert not list(tmp_path.glob("x.*"))  # nothing written


def test_align_step_without_a_reference_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = write_log(tmp_path / "u.log", names=("t", "y1", "u1"))
    assert main(["plot", str(log), "--out", str(tmp_path / "u.png"), "--align", "step"]) == 2
    assert capsys.readouterr().err == (f"quadtank: error: {log}: --align step needs r1 or r2 logged "
                                       "(the steps are found there)\n")


def test_identify_and_design_refuse_a_bad_figure_name_before_working(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    log = write_log(tmp_path / "a.log")
    assert main(["identify", str(log), "--figure", str(tmp_path / "f.gif")]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    assert main(["design", "--model", "1/(10*s+1)", "--figure", str(tmp_path / "f")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "a name without a suffix" in err


def test_design_figure_is_written(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "d.svg"
    assert main(["design", "--model", "1.6592*exp(-2.4*s)/(1.07*s+1)^3", "--figure", str(out)]) == 0
    assert f"figure     {out}" in capsys.readouterr().out
    svg = out.read_text()
    assert 'id="nyquist:circle"' in svg and "<!-- Ms = 1.40 -->" in svg


def test_matplotlib_is_not_loaded_by_the_tui_or_the_cli() -> None:
    """The first frame does not pay for it: only a figure's action or handler loads it."""
    code = ("import sys, quadtank_tui.cli, quadtank_tui.ui.app, quadtank_tui.ui.screens.main, "
            "quadtank_tui.ui.screens.identify, quadtank_tui.ui.screens.design, quadtank_tui.ui.figure_export; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'matplotlib'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == "[]"
