"""`.log`: the thesis's sample is written byte for byte and read back; numpy and
(when present) Octave load what we write; the reader is tolerant where the
original's users were and strict where data would be wrong; a killed run leaves
a loadable file."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest

from quadtank_tui.files.log_writer import LogWriter, format_header, format_tsamp
from quadtank_tui.files.log_reader import LogFileError, parse_log, read_log

GOLDEN = Path(__file__).parent / "golden"
THESIS_STAMP = datetime(1997, 6, 20, 0, 30, 50)
THESIS_ROWS = [
    (0.622070, 0.623535, 0.300000, 0.300000), (0.625000, 0.623047, 0.300000, 0.300000),
    (0.623535, 0.626465, 0.300000, 0.300000), (0.620117, 0.628418, 0.300000, 0.300000),
    (0.623535, 0.628906, 0.300000, 0.300000), (0.619629, 0.627930, 0.300000, 0.300000),
    (0.619629, 0.627930, 0.300000, 0.300000), (0.621094, 0.624023, 0.330000, 0.300000),
    (0.620117, 0.626465, 0.330000, 0.300000), (0.623535, 0.626465, 0.330000, 0.300000),
    (0.625488, 0.628906, 0.330000, 0.300000), (0.628418, 0.628418, 0.330000, 0.300000),
    (0.625977, 0.630371, 0.330000, 0.300000), (0.625488, 0.624512, 0.330000, 0.300000),
    (0.626465, 0.631348, 0.330000, 0.300000), (0.627930, 0.630371, 0.330000, 0.300000),
]
NAMES = ("y1", "y2", "u1", "u2")


class FakeClock:
    """Monotonic seconds the test advances by hand."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _write_thesis_log(path: Path, **kwargs: object) -> LogWriter:
    w = LogWriter(path, NAMES, 1.0, 600, created=THESIS_STAMP, **kwargs)  # type: ignore[arg-type]
    for row in THESIS_ROWS:
        assert w.append(dict(zip(NAMES, row)))
    return w


# --- the thesis's sample --------------------------------------------------------------------

def test_thesis_sample_loads() -> None:
    log = read_log(GOLDEN / "thesis.log")
    assert log.variables == NAMES
    assert log.tsamp == 1.0
    assert log.created == THESIS_STAMP and log.created_text == "Jun 20 00:30:50 1997"
    assert log.rows == 16 and log.duration == 16.0
    assert log.warnings == ()
    np.testing.assert_array_equal(log.data, np.array(THESIS_ROWS))
    assert log["u1"][6:8].tolist() == [0.3, 0.33]
    assert list(log.columns()) == list(NAMES)
    with pytest.raises(KeyError, match="no column 'y3' \\(logged: y1 y2 u1 u2\\)"):
        log["y3"]


def test_writing_the_thesis_sample_is_byte_identical(tmp_path: Path) -> None:
    w = _write_thesis_log(tmp_path / "data.log")
    saved = w.save()
    assert saved == tmp_path / "data.log"
    assert saved.read_bytes() == (GOLDEN / "thesis.log").read_bytes()
    assert sorted(os.listdir(tmp_path)) == ["data.log"]


def test_numpy_loadtxt_reads_what_we_write(tmp_path: Path) -> None:
    path = _write_thesis_log(tmp_path / "data.log").save()
    np.testing.assert_array_equal(np.loadtxt(path, comments="%"), np.array(THESIS_ROWS))


@pytest.mark.skipif(shutil.which("octave") is None, reason="GNU Octave is not installed")
def test_octave_load_reads_what_we_write(tmp_path: Path) -> None:  # pragma: no cover - needs octave
    path = _write_thesis_log(tmp_path / "data.log").save()
    out = subprocess.run(
        ["octave", "--no-gui", "--quiet", "--eval", f"x = load('{path}'); printf('%d %d %.6f\\n', size(x), x(8, 3))"],
        capture_output=True, text=True, timeout=60, check=True,
    )
    assert out.stdout.split() == ["16", "4", "0.330000"]


@pytest.mark.parametrize("seconds, text", [(1.0, "1"), (0.1, "0.1"), (0.05, "0.05"), (2.5, "2.5"), (10, "10"), (0.125, "0.125")])
def test_tsamp_is_the_shortest_exact_decimal(seconds: float, text: str) -> None:
    assert format_tsamp(seconds) == text
    assert format_header(("t", "y1"), seconds, THESIS_STAMP).splitlines()[2] == f"% Logged variables: t y1   TSamp: {text}s"


def test_t_column_and_negative_values(tmp_path: Path) -> None:
    w = LogWriter(tmp_path / "run.log", ("t", "r1", "u2"), 0.05, 3, created=datetime(2026, 3, 5, 7, 8, 9))
    for i in range(3):
        w.append({"t": i * 0.05, "r1": 0.3, "u2": -0.01 * i - (1e-9 if i == 0 else 0.0), "y1": 99.0})
    assert not w.running
    assert w.save().read_text() == (
        "% TANK LOG-file\n% Created on: Mar 05 07:08:09 2026\n% Logged variables: t r1 u2   TSamp: 0.05s\n\n"
        "0.000000  0.300000  0.000000\n0.050000  0.300000  -0.010000\n0.100000  0.300000  -0.020000\n"
    )


def test_append_row_writes_what_append_writes(tmp_path: Path) -> None:
    """The loop's row tuple (LOG_VARIABLES order) gives append's bytes, with the
    columns picked, -0 written unsigned, and nan / inf refused by name."""
    names = ("t", "u2", "y1", "r2")
    rows = [(0.05 * i, 0.1 * i, -1e-9 * i, 0.3, 7.0, -0.0, (-1) ** i * 2.5, 12.34567891, -1e-7) for i in range(4)]
    by_map = LogWriter(tmp_path / "m.log", names, 0.05, 10, created=THESIS_STAMP)
    by_row = LogWriter(tmp_path / "r.log", names, 0.05, 10, created=THESIS_STAMP)
    for row in rows:
        assert by_map.append(dict(zip(("t", "y1", "y2", "y3", "y4", "u1", "u2", "r1", "r2"), row)))
        assert by_row.append_row(row)
    text = by_row.save().read_text()
    assert text == by_map.save().read_text()
    assert text.splitlines()[4:6] == ["0.000000  2.500000  0.000000  0.000000",
                                      "0.050000  -2.500000  0.100000  0.000000"]
    w = LogWriter(tmp_path / "b.log", ("y1", "u1"), 1.0, 10)
    with pytest.raises(LogFileError, match="not a finite number: u1"):
        w.append_row((0.0, 0.5, 0.0, 0.0, 0.0, float("-inf"), 0.0, 0.0, 0.0))
    with pytest.raises(LogFileError, match="not a finite number: y1"):
        w.append_row((0.0, float("nan"), 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0))
    assert w.rows == 0


# --- LogOn / LogOff / progress / Save ---------------------------------------------------------

def test_points_limit_progress_and_logoff(tmp_path: Path) -> None:
    w = LogWriter(tmp_path / "p.log", ("y1",), 0.1, 4, created=THESIS_STAMP)
    assert (w.running, w.progress, w.partial_path.name) == (True, 0.0, "p.log.partial")
    assert read_log(w.partial_path).rows == 0  # loadable from LogOn on
    for i in range(3):
        assert w.append({"y1": i / 10})
    assert w.progress == 0.75
    assert w.append({"y1": 0.3}) and w.progress == 1.0 and not w.running
    assert not w.append({"y1": 0.4})  # the points limit stopped it
    assert read_log(w.save()).data[:, 0].tolist() == [0.0, 0.1, 0.2, 0.3]


def test_logoff_before_the_limit_then_save_elsewhere(tmp_path: Path) -> None:
    w = LogWriter(tmp_path / "a.log", ("u1",), 1.0, 100, created=THESIS_STAMP)
    w.append({"u1": 0.5})
    w.stop()
    assert not w.append({"u1": 0.6})
    out = w.save(tmp_path / "b.log")
    assert read_log(out).data.tolist() == [[0.5]]
    assert sorted(os.listdir(tmp_path)) == ["b.log"]


def _die(writer: LogWriter) -> None:
    """What SIGKILL does to a writer: its file is closed (the lock with it), the
    partial file stays."""
    writer._file.close()


def test_logon_keeps_a_partial_left_by_a_run_that_died(tmp_path: Path) -> None:
    first = LogWriter(tmp_path / "data.log", ("y1",), 1.0, 10, created=THESIS_STAMP)
    first.append({"y1": 0.25})
    _die(first)
    second = LogWriter(tmp_path / "data.log", ("y1",), 1.0, 10, created=THESIS_STAMP)
    assert second.recovered == (tmp_path / "data-recovered.log",)
    assert read_log(second.recovered[0]).data.tolist() == [[0.25]]
    second.append({"y1": 0.5})
    _die(second)
    third = LogWriter(tmp_path / "data.log", ("y1",), 1.0, 10)
    assert third.recovered == (tmp_path / "data-recovered-2.log",)
    assert first.recovered == ()
    third.append({"y1": 0.75})
    third.save()
    assert sorted(os.listdir(tmp_path)) == ["data-recovered-2.log", "data-recovered.log", "data.log"]
    assert read_log(tmp_path / "data.log").data.tolist() == [[0.75]]


def test_a_header_only_partial_is_reused_not_recovered(tmp_path: Path) -> None:
    _die(LogWriter(tmp_path / "data.log", ("y1",), 1.0, 10))
    w = LogWriter(tmp_path / "data.log", ("y1",), 1.0, 10)
    assert (w.recovered, w.partial_path.name) == ((), "data.log.partial")
    w.close()  # Exit without a row: nothing is left behind
    assert os.listdir(tmp_path) == []


def test_two_writers_of_one_name_keep_their_own_rows(tmp_path: Path) -> None:
    """Two runs logging as `data` into one folder: each partial file is its
    writer's (the second does not take, truncate or "recover" the first's), and
    each saved file holds that run's rows."""
    a = LogWriter(tmp_path / "data.log", ("y1",), 1.0, 10, created=THESIS_STAMP)
    b = LogWriter(tmp_path / "data.log", ("y1",), 1.0, 10, created=THESIS_STAMP)
    assert (a.partial_path.name, b.partial_path.name, b.recovered) == ("data.log.partial", "data.log.2.partial", ())
    for i in range(3):
        a.append({"y1": 0.1 * i})
        b.append({"y1": 0.5 + 0.1 * i})
    assert a.save(tmp_path / "a.log") == tmp_path / "a.log"
    c = LogWriter(tmp_path / "data.log", ("y1",), 1.0, 10)  # while b still holds its partial file
    assert (c.partial_path.name, c.recovered) == ("data.log.partial", ())
    b.append({"y1": 0.9})
    with pytest.raises(FileExistsError):
        b.save(tmp_path / "a.log", replace=False)  # a collision on the final name
    assert b.save(tmp_path / "b.log", replace=False) == tmp_path / "b.log"
    assert read_log(tmp_path / "a.log").data[:, 0].tolist() == pytest.approx([0.0, 0.1, 0.2])
    assert read_log(tmp_path / "b.log").data[:, 0].tolist() == pytest.approx([0.5, 0.6, 0.7, 0.9])
    c.discard()
    assert sorted(os.listdir(tmp_path)) == ["a.log", "b.log"]


_HOLDER = """
import sys
from quadtank_tui.files.log_writer import LogWriter
w = LogWriter(sys.argv[1], ("y1",), 1.0, 100)
w.append({"y1": 0.25})
print(w.partial_path.name, flush=True)
sys.stdin.readline()
w.append({"y1": 0.5})
print(w.save(sys.argv[2]), flush=True)
"""


def test_another_process_logging_under_the_same_name_is_left_alone(tmp_path: Path) -> None:
    """The lock holds across processes: a live run's partial file (with rows) is
    not mistaken for a dead run's and moved away."""
    child = subprocess.Popen([sys.executable, "-c", _HOLDER, str(tmp_path / "data.log"), str(tmp_path / "a.log")],
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert child.stdin is not None and child.stdout is not None
    try:
        assert child.stdout.readline().strip() == "data.log.partial"
        mine = LogWriter(tmp_path / "data.log", ("y1",), 1.0, 100)
        assert (mine.partial_path.name, mine.recovered) == ("data.log.2.partial", ())
        mine.append({"y1": 0.75})
        child.stdin.write("go\n")
        child.stdin.flush()
        assert child.stdout.readline().strip() == str(tmp_path / "a.log")
    finally:
        child.kill() if child.poll() is None else None
        child.wait(timeout=30)
    assert read_log(tmp_path / "a.log").data.tolist() == [[0.25], [0.5]]
    assert read_log(mine.save()).data.tolist() == [[0.75]]


def test_discard(tmp_path: Path) -> None:
    w = LogWriter(tmp_path / "a.log", ("u1",), 1.0, 100)
    w.append({"u1": 0.5})
    w.discard()
    assert os.listdir(tmp_path) == []


def test_rows_are_on_disk_as_they_come(tmp_path: Path) -> None:
    w = LogWriter(tmp_path / "a.log", ("y1", "y2"), 1.0, 100, created=THESIS_STAMP)
    for i in range(5):
        w.append({"y1": i, "y2": -i})
        assert read_log(w.partial_path).rows == i + 1


def test_batched_flush_every_n_rows(tmp_path: Path) -> None:
    clock = FakeClock()
    w = LogWriter(tmp_path / "a.log", ("y1",), 1.0, 100, created=THESIS_STAMP, flush_rows=3, clock=clock)
    for i in range(5):
        w.append({"y1": i})
    assert read_log(w.partial_path).rows == 3
    w.stop()
    assert read_log(w.partial_path).rows == 5


def test_fsync_at_most_once_a_second(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    clock = FakeClock()
    w = LogWriter(tmp_path / "a.log", ("y1",), 0.1, 100, clock=clock)
    synced: list[float] = []
    real_fsync = os.fsync

    def fsync(fd: int) -> None:
        synced.append(clock.now)
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    for i in range(25):
        clock.now = i * 0.1
        w.append({"y1": 0.5})
    assert synced == [1.0, 2.0]


def test_writer_refuses_bad_requests(tmp_path: Path) -> None:
    with pytest.raises(LogFileError, match="must be distinct names"):
        LogWriter(tmp_path / "a.log", ("y1", "y9"), 1.0, 10)
    with pytest.raises(LogFileError, match="points must be a whole number >= 1"):
        LogWriter(tmp_path / "a.log", ("y1",), 1.0, 0)
    with pytest.raises(ValueError, match="TSamp must be a positive number"):
        LogWriter(tmp_path / "a.log", ("y1",), 0.0, 10)
    assert os.listdir(tmp_path) == []
    w = LogWriter(tmp_path / "a.log", ("y1", "u1"), 1.0, 10)
    with pytest.raises(LogFileError, match="sample has no value for 'u1'"):
        w.append({"y1": 0.5})
    with pytest.raises(LogFileError, match="not a finite number: y1"):
        w.append({"y1": float("nan"), "u1": 0.5})
    assert w.rows == 0


# --- tolerant, strict reading -------------------------------------------------------------------

def test_crlf_trailing_blanks_extra_comments_no_created_line() -> None:
    text = (b"% TANK LOG-file\r\n% Logged variables: y1 u1   TSamp: 0.1s  \r\n% operator: jln\r\n\r\n"
            b"0.500000  0.300000   \r\n% step on u1 here\r\n0.510000\t0.400000 % inline note\r\n\r\n")
    log = parse_log(text, name="x.log")
    assert log.variables == ("y1", "u1") and log.tsamp == 0.1
    assert log.data.tolist() == [[0.5, 0.3], [0.51, 0.4]]
    assert log.created is None
    assert log.warnings == ("x.log: no 'Created on:' line",)


def test_header_variants() -> None:
    assert parse_log("% Logged variables: y1 y2\n1 2\n").tsamp is None
    assert parse_log("% Logged variables: y1   TSamp: 2 s\n1\n").tsamp == 2.0
    log = parse_log("% TANK LOG-file\n% Created on: Jun  5 00:30:50 1997\n% Logged variables: y1 q7   TSamp: 1s\n\n1 2\n",
                    name="l")
    assert log.created == datetime(1997, 6, 5, 0, 30, 50)
    assert log.warnings == ("l, line 3: unusual variable names q7 (kept)",)


@pytest.mark.parametrize(
    "text, message",
    [
        ("% Logged variables: y1 y2   TSamp: 1s\n\n0.1  0.2\n0.3\n0.4  0.5\n",
         "x.log, line 4: 1 values where the header declares 2 (y1 y2)"),
        ("% Logged variables: y1 y2   TSamp: 1s\n\n0.1  0.2  0.3\n", "x.log, line 3: 3 values where the header declares 2 (y1 y2)"),
        ("% Logged variables: y1 y2   TSamp: 1s\n\n0.1  abc\n", "x.log, line 3: not a number in '0.1  abc'"),
        ("% Logged variables: y1 y2   TSamp: 1s\n\n0.1  nan\n0.2  0.3\n", "x.log, line 3: not a number in '0.1  nan'"),
        ("% TANK LOG-file\n\n0.1  0.2\n", "x.log, line 3: data before the '% Logged variables:' header line"),
        ("% TANK LOG-file\n", "x.log, line 1: no '% Logged variables:' header line: not a TANK log file"),
        ("% Logged variables: y1 y1   TSamp: 1s\n", "x.log, line 1: a variable is named twice: y1 y1"),
        ("% Logged variables: y1   TSamp: -1s\n", "x.log, line 1: TSamp is not a positive number of seconds: '-1'"),
        ("% Logged variables:    TSamp: 1s\n", "x.log, line 1: no variable names on the 'Logged variables:' line"),
        ("% TANK PAR-file\nSIMULATION\n", "x.log, line 1: this is a .par parameter file, not a .log"),
    ],
)
def test_refused_logs_name_file_and_line(text: str, message: str) -> None:
    with pytest.raises(LogFileError) as info:
        parse_log(text.encode(), name="x.log")
    assert str(info.value) == message


def test_binary_junk_is_refused_with_its_line() -> None:
    with pytest.raises(LogFileError, match=r"x.log, line 3: not a number"):
        parse_log(b"% Logged variables: y1\n0.5\n\x89PNG\x00\xff\n", name="x.log")


def test_an_unterminated_incomplete_last_row_is_dropped_with_a_warning() -> None:
    log = parse_log(b"% Logged variables: y1 y2   TSamp: 1s\n\n0.1  0.2\n0.3  0.4\n0.5  0.", name="k.log")
    assert log.data.tolist() == [[0.1, 0.2], [0.3, 0.4]]  # "0." is a number, but cut short
    assert log.warnings[0] == "k.log, line 5: incomplete last row dropped (file cut off while writing)"
    head = b"% Logged variables: y1 u1   TSamp: 1s\n\n0.622070  0.300000\n"
    torn = parse_log(head + b"0.623535  0.300", name="k.log")  # disk full mid-number
    assert torn.data.tolist() == [[0.622070, 0.3]] and "incomplete last row dropped" in torn.warnings[0]
    whole = parse_log(head + b"0.623535  0.300000", name="k.log")  # only the line end missing
    assert whole.rows == 2 and not any("incomplete" in w for w in whole.warnings)
    log = parse_log(b"% Logged variables: y1 y2   TSamp: 1s\n\n0.1  0.2\n0.3", name="k.log")
    assert log.data.tolist() == [[0.1, 0.2]]
    assert "k.log, line 4: incomplete last row dropped (file cut off while writing)" in log.warnings


def test_missing_file() -> None:
    with pytest.raises(LogFileError, match="nope.log: no such file"):
        read_log("nope.log")


# --- a run killed mid-logging ----------------------------------------------------------------------

_CHILD = """
import sys
from quadtank_tui.files.log_writer import LogWriter
w = LogWriter(sys.argv[1], ("t", "y1"), 0.1, 100000, flush_rows=10)
i = 0
while True:
    w.append({"t": i * 0.1, "y1": (i % 1000) / 1000})
    i += 1
    if i % 10 == 0:
        print(i, flush=True)
"""


def test_sigkill_mid_logging_leaves_every_flushed_row(tmp_path: Path) -> None:
    target = tmp_path / "killed.log"
    child = subprocess.Popen([sys.executable, "-c", _CHILD, str(target)], stdout=subprocess.PIPE, text=True)
    assert child.stdout is not None
    try:
        flushed = 0
        while flushed < 500:
            flushed = int(child.stdout.readline())
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait(timeout=30)
    assert child.returncode == -signal.SIGKILL
    assert not target.exists()
    log = read_log(target.with_name("killed.log.partial"))
    assert log.variables == ("t", "y1") and log.tsamp == 0.1
    assert log.rows >= flushed and log.rows % 10 == 0  # whole flushes only, no torn row
    i = np.arange(log.rows)
    np.testing.assert_allclose(log["t"], i * 0.1, atol=5e-7)
    np.testing.assert_array_equal(log["y1"], (i % 1000) / 1000)
