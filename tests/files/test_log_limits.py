"""A log is read as a stream with row, line and column limits (issue 24: a 50 MB
log took 742 MB to identify, one line of 10 million columns 1.3 GB to refuse).
The limits are parameters of read_log, set low here so the files stay small;
benchmarks/bounded_work.py gives the figures on the big files."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest

from quadtank_tui.cli import main
from quadtank_tui.files.log_writer import format_header, format_row
from quadtank_tui.files.log_reader import LogFileError, read_log
from quadtank_tui.files.stamp import parse_stamp

_STAMP = parse_stamp("Nov 26 12:00:00 2026")
assert _STAMP is not None
CREATED: datetime = _STAMP


def write_log(path: Path, rows: int, variables: tuple[str, ...] = ("y1", "y2", "u1", "u2")) -> Path:
    with path.open("w") as f:
        f.write(format_header(variables, 0.1, CREATED))
        for k in range(rows):
            f.write(format_row([0.5 + 1e-6 * k] * len(variables)))
    return path


def test_a_line_longer_than_the_limit_is_refused_with_its_number(tmp_path: Path) -> None:
    log = write_log(tmp_path / "a.log", 3)
    with log.open("a") as f:
        f.write(" ".join(["0.5"] * 100) + "\n")  # 399 characters
    with pytest.raises(LogFileError, match=r"a\.log, line 8: a line longer than 200 characters: not a TANK log"):
        read_log(log, max_line=200)
    assert read_log(write_log(tmp_path / "b.log", 3), max_line=200).rows == 3


def test_an_unterminated_line_longer_than_the_limit_is_refused_too(tmp_path: Path) -> None:
    log = tmp_path / "wide.log"
    log.write_text("% TANK LOG-file\n% Logged variables: y1 y2   TSamp: 0.1s\n\n" + "0.5 " * 300)
    with pytest.raises(LogFileError, match="line 4: a line longer than 100 characters"):
        read_log(log, max_line=100)


def test_more_rows_than_the_limit_are_refused_naming_the_line(tmp_path: Path) -> None:
    log = write_log(tmp_path / "long.log", 11)
    assert read_log(log, max_rows=11).rows == 11
    with pytest.raises(LogFileError, match=r"long\.log, line 15: more than 10 rows"):
        read_log(log, max_rows=10)


def test_a_header_of_too_many_variables_is_refused(tmp_path: Path) -> None:
    log = tmp_path / "many.log"
    log.write_text("% TANK LOG-file\n% Logged variables: " + " ".join(f"v{i}" for i in range(65))
                   + "   TSamp: 1s\n\n")
    with pytest.raises(LogFileError, match="line 2: 65 variables on the 'Logged variables:' line: a log "
                       "has at most 64"):
        read_log(log)


def test_the_cli_says_it_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    import quadtank_tui.files.log_reader as logmod

    monkeypatch.setattr(logmod, "MAX_LINE", 64)
    log = tmp_path / "wide.log"
    log.write_text("% TANK LOG-file\n% Logged variables: y1   TSamp: 1s\n\n" + "0.5 " * 100 + "\n")
    monkeypatch.setattr(logmod.read_log, "__kwdefaults__", {"max_rows": logmod.MAX_ROWS, "max_line": 64,
                                                                 "max_bytes": None})
    assert main(["log", "info", str(log)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"quadtank: error: {log}, line 4: a line longer than 64 characters: not a TANK log "
                   "(a row is a few numbers)"]


def test_the_rows_read_are_the_values_written(tmp_path: Path) -> None:
    log = write_log(tmp_path / "v.log", 5)
    data = read_log(log).data
    assert data.dtype == np.float64 and data.shape == (5, 4)
    np.testing.assert_array_equal(data[:, 0], [0.5, 0.500001, 0.500002, 0.500003, 0.500004])


#: In a fresh interpreter: the resident memory (kB) before reading the log and its
#: peak while reading (the peak is reset first: /proc/self/clear_refs, Linux >= 4.0).
PEAK = textwrap.dedent("""
    import sys
    from quadtank_tui.files.log_reader import read_log

    def status(field):
        with open("/proc/self/status") as f:
            return next(int(line.split()[1]) for line in f if line.startswith(field + ":"))

    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    before = status("VmRSS")
    log = read_log(sys.argv[1])
    print(before, status("VmHWM"), log.rows)
""")


def test_reading_a_log_takes_a_few_times_its_size_in_memory(tmp_path: Path) -> None:
    log = tmp_path / "m.log"
    row = format_row([0.5] * 9)
    log.write_text(format_header(("t", "y1", "y2", "y3", "y4", "u1", "u2", "r1", "r2"), 0.1, CREATED)
                   + row * 40_000)
    size = log.stat().st_size  # 3.3 MB; the values are 2.9 MB as float64
    out = subprocess.run([sys.executable, "-c", PEAK, str(log)], capture_output=True, text=True, check=True)
    before, after, rows = (int(w) for w in out.stdout.split())
    assert rows == 40_000
    grown = (after - before) * 1024
    # Measured: +2.9 MB for these 3.6 MB (the float64 buffer); before, +36.9 MB (10.4 times).
    print(f'{size} bytes read, peak RSS +{grown} bytes')
    assert grown < 2 * size, f"reading {size} bytes grew the peak RSS by {grown} bytes"
