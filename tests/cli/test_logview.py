"""`quadtank log plot` and `quadtank log compare` on logs of headless runs."""

from __future__ import annotations

import os
import re
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest

from quadtank_tui.cli import main
from quadtank_tui.commands.logview import envelope
from quadtank_tui.engine.headless import run_headless
from quadtank_tui.files.log_writer import format_header, format_row
from quadtank_tui.files.script import parse_script

ROOT = Path(__file__).parents[2]
SESSION = (ROOT / "params" / "sample_session.yaml").read_text()


def session_log(folder: Path, name: str, k1: float) -> Path:
    """The thesis's sample session (step of reference one by +0.1 at 610 s) with
    the references logged, and loop 1's gain K = k1."""
    text = SESSION.replace('"LOGGING.Variables": y1 y2 u1 u2', '"LOGGING.Variables": t y1 y2 u1 u2 r1 r2')
    text = text.replace('"CONTROLLER ONE.K": 3.0', f'"CONTROLLER ONE.K": {k1}')
    out = folder / "logs" / f"{name}.log"
    result = run_headless(par=str(ROOT / "params" / "minphase.par"), script=parse_script(text, name=name),
                          duration=1200.0, out=out, params_dir=folder / "params")
    assert result.status == 0, result.text
    return out


def test_compare_prints_both_runs_step_figures_side_by_side(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    session_log(Path("."), "k3", 3.0)
    session_log(Path("."), "k6", 6.0)
    capsys.readouterr()
    assert main(["log", "compare", "logs/k3.log", "logs/k6.log"]) == 0
    # The figures the headless run's summary gives for the same runs (5.1 %, 53 s
    # and 4.1 %, 34 s); the step comes 10 s after LogOn.
    assert capsys.readouterr().out == (
        "                  logs/k3.log      logs/k6.log\n"
        "rows x TSamp      600 x 1 s        600 x 1 s\n"
        "loop 1 (y1, r1)\n"
        "  last step       +0.100 at 10 s   +0.100 at 10 s\n"
        "  rise 10-90 %    13 s             6 s\n"
        "  overshoot       5.1 %            4.1 %\n"
        "  settling 2 %    53 s             34 s\n"
        "  IAE             0.817            0.459\n"
        "  final error     +0.00000         +0.00000\n"
        "loop 2 (y2, r2)\n"
        "  last step       none             none\n"
        "  rise 10-90 %    -                -\n"
        "  overshoot       -                -\n"
        "  settling 2 %    -                -\n"
        "  IAE             0.389            0.389\n"
        "  final error     +0.00000         +0.00000\n")


def test_compare_says_which_loop_was_not_logged(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "plain.log"
    log.write_text(format_header(("y1", "y2", "u1", "u2"), 1.0, datetime(2026, 1, 5))
                   + "".join(format_row((0.5, 0.5, 0.3, 0.3)) for _ in range(5)))
    assert main(["log", "compare", str(log), str(log)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^  last step\s+r1 not logged\s+r1 not logged$", out, re.M), out


#: A y label and the rest of its row in plotext's text.
_ROW = re.compile(r"^\s*(-?\d+(?:\.\d+)?)?\s*[┤│](.*)$")


def read_level(plot: str) -> tuple[float, float]:
    """The value of the one horizontal curve of `plot`, read as a person reads it:
    from the labels of the rows around it; and the value of half a row."""
    rows = [(_ROW.match(line), line) for line in plot.splitlines()]
    labels = {i: float(m.group(1)) for i, (m, _) in enumerate(rows) if m and m.group(1)}
    curve = [i for i, (m, _) in enumerate(rows) if m and any(0x2801 <= ord(ch) <= 0x28FF for ch in m.group(2))]
    assert len(curve) == 1 and len(labels) >= 2, plot
    (top, v_top), (bottom, v_bottom) = min(labels.items()), max(labels.items())
    per_row = (v_bottom - v_top) / (bottom - top)
    return v_top + (curve[0] - top) * per_row, abs(per_row) / 2


@pytest.mark.parametrize("size", [(80, 20), (120, 40), (61, 13)])
def test_plot_reads_back_a_known_level(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                       size: tuple[int, int]) -> None:
    log = tmp_path / "level.log"
    log.write_text(format_header(("t", "y1", "u1"), 0.5, datetime(2026, 1, 5))
                   + "".join(format_row((0.5 * k, 0.437, 0.3 + 0.001 * k)) for k in range(240)))
    assert main(["log", "plot", str(log), "--vars", "y1", "--width", str(size[0]),
                 "--height", str(size[1])]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert lines[0] == f"{log}  y1  (t in s)" and len(lines) == size[1]
    assert "\x1b" not in out  # not a terminal: no colour codes
    value, half_row = read_level(out)
    assert abs(value - 0.437) <= half_row, out
    labels = [float(m.group(1)) for m, _ in ((_ROW.match(x), x) for x in lines) if m and m.group(1)]
    assert all(abs(v * 1000 - round(v * 1000)) < 1e-9 for v in labels), labels  # round numbers
    ticks = [float(x) for x in lines[-1].split()]
    assert ticks[0] == 0 and all(v == round(v) for v in ticks), ticks  # round seconds


@pytest.mark.parametrize(("argv", "message"), [
    (["log", "plot", "LOG", "--vars", "y1", "y9"], "LOG: no column y9 (logged: t y1 u1)"),
    (["log", "plot", "BAD"], "BAD, line 3: 2 values where the header declares 1 (y1)"),
    (["log", "compare", "LOG", "MISSING"], "MISSING: no such file"),
    # issue 41: 60 s and 11.5 GB to a MemoryError; 3.8 GB
    (["log", "plot", "LOG", "--width", "100000000"], "--width must be 1..2000 characters, got 100000000"),
    (["log", "plot", "LOG", "--height", "10000000"], "--height must be 1..1000 characters, got 10000000"),
    # a 200 MB log (4.2 million rows): 166 s and 2.55 GB; refused from its size (a sparse file here)
    (["log", "plot", "HUGE"], "HUGE: 200.0 MB, larger than log plot reads (64 MB, about 688,172 rows of 9 columns)"),
    (["run", "--inputs-from", "HUGE", "--log", "OUT"],
     "HUGE: 200.0 MB, larger than a replay reads (20 MB, about 215,053 rows of 9 columns): replay a part of it"),
])
def test_bad_logs_are_one_line_naming_file_and_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                    argv: list[str], message: str) -> None:
    paths = {"LOG": tmp_path / "ok.log", "BAD": tmp_path / "bad.log", "MISSING": tmp_path / "none.log",
             "HUGE": tmp_path / "huge.log", "OUT": tmp_path / "out.log"}
    paths["LOG"].write_text(format_header(("t", "y1", "u1"), 1.0, datetime(2026, 1, 5)) + format_row((0, 1, 2)))
    paths["HUGE"].write_text(paths["LOG"].read_text())
    os.truncate(paths["HUGE"], 200_000_000)  # sparse: no 200 MB written
    paths["BAD"].write_text("% Logged variables: y1   TSamp: 1s\n1\n2 3\n")
    argv = [str(paths.get(a, a)) for a in argv]
    assert main(argv) == 2
    expected = message
    for key, path in paths.items():
        expected = expected.replace(key, str(path))
    assert capsys.readouterr().err.splitlines()[-1] == f"quadtank: error: {expected}"
    assert not paths["OUT"].exists()


def test_a_long_log_is_drawn_from_its_envelope_with_every_spike(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    """40,000 rows at 80 columns: the curve is drawn from each braille column's
    lowest and highest rows (plotext drew every row: minutes and gigabytes for a
    long log), and a spike of one row still reaches the top of the plot."""
    n = 40_000
    y = np.full(n, 0.25)
    y[23_457] = 0.75  # one row
    header = format_header(("t", "y1"), 0.05, datetime(2026, 1, 5))
    path = tmp_path / "long.log"
    path.write_text(header + "".join(f"{0.05 * k:.2f} {v:.4f}\n" for k, v in enumerate(y)))
    keep = envelope(y, 160)
    assert len(keep) <= 2 * 160 + 4 and 23_457 in keep and keep[0] == 0 and keep[-1] == n - 1
    assert main(["log", "plot", str(path), "--width", "80", "--height", "20"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if "│" in line or "┤" in line]
    drawn = [line for line in rows if any(0x2800 < ord(ch) <= 0x28FF for ch in line)]
    labelled = {line.split("┤")[0].strip(): line for line in rows if "┤" in line}
    assert labelled["0.6"] in drawn and labelled["0.4"] in drawn  # the spike of one row, up to 0.75
    assert len(drawn) >= 8 and re.search(r"([\u2801-\u28ff])\1{9}", drawn[-1])  # and the level of 0.25 across


def test_plot_without_colour_tells_curves_apart_by_marker(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 28: without colour each curve has its character, named in the title;
    the reference is dotted and the level drawn over it."""
    log = tmp_path / "two.log"
    log.write_text(format_header(("t", "y1", "r1"), 0.5, datetime(2026, 1, 5))
                   + "".join(format_row((0.5 * k, 0.4, 0.6)) for k in range(240)))
    assert main(["log", "plot", str(log), "--vars", "y1", "r1", "--width", "80", "--height", "20"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"{log}  * y1  · r1  (t in s)"
    rows = [(_ROW.match(line), line) for line in lines[1:]]
    labels = {i: float(m.group(1)) for i, (m, _) in enumerate(rows) if m and m.group(1)}
    (top, v_top), (bottom, v_bottom) = min(labels.items()), max(labels.items())
    per_row = (v_bottom - v_top) / (bottom - top)
    for marker, level in (("*", 0.4), ("·", 0.6)):
        (row,) = [i for i, (m, _) in enumerate(rows) if m and marker in m.group(2)]
        assert abs(v_top + (row - top) * per_row - level) <= abs(per_row) / 2
        plotted = rows[row][0]
        assert plotted is not None
        if marker == "·":  # dotted: a dot every DOT_GAP columns, not a line
            assert 20 <= plotted.group(2).count("·") <= 45


def test_a_level_on_its_reference_shows_both(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 43: y1 settled on r1 (the same values) draws both, in a pipe as two
    markers on the one row and in colour as both colours: the cells they share
    take them in turn (plotext kept only the one drawn last)."""
    from quadtank_tui.commands.logview import render_plot
    from quadtank_tui.files.log_reader import read_log
    from quadtank_tui.ui.colours import SIGNALS

    log = tmp_path / "on.log"
    log.write_text(format_header(("t", "y1", "r1"), 0.5, datetime(2026, 1, 5))
                   + "".join(format_row((0.5 * k, 0.5, 0.5)) for k in range(240)))
    assert main(["log", "plot", str(log), "--vars", "y1", "r1", "--width", "80", "--height", "20"]) == 0
    (row,) = [line for line in capsys.readouterr().out.splitlines()[1:] if "*" in line]
    assert row.count("*") >= 30 and row.count("·") >= 8
    data = read_log(str(log))
    coloured = render_plot(data, np.arange(data.rows) * 0.5, ["y1", "r1"], 80, 20, colour=True, title="on")
    for name in ("y1", "ref1"):
        r, g, b = SIGNALS[name].dark
        assert coloured.count(f"38;2;{r};{g};{b}m") >= 3, name  # the title's and the plot's cells
