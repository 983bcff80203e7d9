"""`quadtank run` never loses or mixes logged data: two runs logging under one
name, a run longer than the Logging window's Points limit, a full disk, a
read-only logs folder, a run that logged nothing (issue 18, items 4-6 and 15)."""

from __future__ import annotations

import errno
import os
from datetime import datetime
from pathlib import Path

import pytest

import quadtank_tui.core.parameters.settings as parameter_settings
import quadtank_tui.engine.headless as headless
import quadtank_tui.files.log_writer as log_module
from quadtank_tui.cli import main
from quadtank_tui.files.log_writer import LogWriter
from quadtank_tui.files.log_reader import LogFileError, read_log

SCRIPT_LOGGING_AS_DATA = """
- at: 0
  set: {"LOGGING.LogFile": data, "LOGGING.Points": 50}
- {at: 0, state: Run}
- {at: 0, log: on}
"""


def test_two_runs_logging_as_data_in_one_folder_keep_their_own_rows(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """The issue's case: both runs log under LOGGING.LogFile `data` into one
    folder (run B starts while A is logging).  Each --log file holds its own
    run's rows (A: 50 rows of a u1 = 0.30 run, B: 50 of u1 = 0.70), nothing is
    "recovered" from a live run, and no partial file is left."""
    script = tmp_path / "s.yaml"
    script.write_text(SCRIPT_LOGGING_AS_DATA)
    real = headless.run_experiment
    inner: list[int] = []

    def b_runs_meanwhile(engine, scr, duration, watch=None):
        if inner:  # B itself
            return real(engine, scr, duration)
        real(engine, scr, duration / 2)  # A is logging
        inner.append(-1)
        inner[0] = main(["run", "--par", str(par(tmp_path, "b", 0.70)), "--script", str(script),
                         "--duration", "8", "--log", str(tmp_path / "b.log")])
        return engine.run_for(duration / 2)  # A goes on (its events are all at 0)

    monkeypatch.setattr(headless, "run_experiment", b_runs_meanwhile)
    assert main(["run", "--par", str(par(tmp_path, "a", 0.30)), "--script", str(script),
                 "--duration", "8", "--log", str(tmp_path / "a.log")]) == 0
    assert inner == [0]
    out = capsys.readouterr().out
    assert f"{tmp_path / 'a.log'} (50 rows)" in out and f"{tmp_path / 'b.log'} (50 rows)" in out
    assert set(read_log(tmp_path / "a.log")["u1"]) == {0.3}
    assert set(read_log(tmp_path / "b.log")["u1"]) == {0.7}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.log", "a.par", "b.log", "b.par", "s.yaml"]


def test_a_run_saving_the_same_log_meanwhile_is_not_overwritten(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """A collision on the final name: run B (20 s) saves run.log while run A (30 s)
    is still going.  A does not replace B's log: it saves run-2.log and says so;
    each file holds its own run's rows.  A run.log from before both runs is
    replaced as always (a rerun)."""
    out = tmp_path / "run.log"
    out.write_text("an earlier run's log\n")
    real = headless.run_experiment
    inner: list[int] = []

    def b_runs_meanwhile(engine, scr, duration, watch=None):
        if not inner:
            inner.append(-1)
            inner[0] = main(["run", "--duration", "20", "--log", str(out)])
        return real(engine, scr, duration)

    monkeypatch.setattr(headless, "run_experiment", b_runs_meanwhile)
    assert main(["run", "--duration", "30", "--log", str(out)]) == 0
    captured = capsys.readouterr()
    assert inner == [0]
    assert f"log        {out} (200 rows)" in captured.out
    assert f"log        {tmp_path / 'run-2.log'} (300 rows)" in captured.out
    assert f"{out} was written by another run meanwhile: this run's log is {tmp_path / 'run-2.log'}" in captured.err
    assert (read_log(out).rows, read_log(tmp_path / "run-2.log").rows) == (200, 300)
    assert sorted(os.listdir(tmp_path)) == ["run-2.log", "run.log"]


def test_without_a_script_every_sample_is_logged_beyond_the_points_limit(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """docs/headless.md's promise: a run without a script logs every sample.  With the
    Logging window's limit lowered to 5,000 (it is 100,000: 8 h at 50 ms is 576,000
    samples; 11 s to run), a 6,000-sample run still logs 6,000 rows."""
    monkeypatch.setattr(parameter_settings, "POINTS_MAX", 5000)
    monkeypatch.setattr(headless, "POINTS_MAX", 5000, raising=False)
    assert main(["run", "--duration", "600", "--log", str(tmp_path / "all.log")]) == 0
    assert read_log(tmp_path / "all.log").rows == 6000


class _FullDisk:
    """A log file on a disk with `room` bytes left: writes what fits, then
    OSError(ENOSPC), as a short write followed by a failed one does."""

    def __init__(self, real, room: int) -> None:
        self.real, self.room = real, room

    def write(self, data) -> int:
        if self.room <= 0:
            raise OSError(errno.ENOSPC, "No space left on device")
        n = self.real.write(bytes(data[: self.room]))
        self.room -= n
        return n

    def __getattr__(self, name: str):
        return getattr(self.real, name)


def test_disk_full_leaves_whole_rows_and_says_how_many(tmp_path: Path) -> None:
    w = LogWriter(tmp_path / "full.log", ("y1", "u1"), 1.0, 100, created=datetime(2000, 1, 1))
    # two rows of "0.300000  0.300000\n", then 5 bytes; a stand-in for the file, not a FileIO
    w._file = _FullDisk(w._file, room=2 * 18 + 5)  # type: ignore[assignment]
    w.append({"y1": 0.3, "u1": 0.3})
    w.append({"y1": 0.3, "u1": 0.3})
    with pytest.raises(LogFileError, match=r"full.log: cannot write \(No space left on device\): logging "
                       r"stopped; the 2 whole rows written are kept"):
        w.append({"y1": 0.3, "u1": 0.3})
    assert (w.running, w.rows) == (False, 2)
    assert not w.append({"y1": 0.3, "u1": 0.3})
    text = w.partial_path.read_text()
    assert text.endswith("\n0.300000  0.300000\n0.300000  0.300000\n")  # the torn 5 bytes were cut back
    assert read_log(w.save()).rows == 2


def test_a_batch_of_rows_the_disk_fills_in_keeps_the_whole_rows_it_took(tmp_path: Path) -> None:
    # The file thread (and an inline drive) writes the rows of a millisecond in one
    # write: the disk taking three and a half of five keeps three, not none.
    w = LogWriter(tmp_path / "full.log", ("y1", "u1"), 1.0, 100, created=datetime(2000, 1, 1))
    w.append({"y1": 0.1, "u1": 0.1})
    w._file = _FullDisk(w._file, room=3 * 18 + 9)  # type: ignore[assignment]
    with pytest.raises(LogFileError, match=r"the 4 whole rows written are kept"):
        with w.held():
            for k in range(2, 7):
                w.append_row((0.0, k / 10, 0.0, 0.0, 0.0, k / 10, 0.0, 0.0, 0.0))
    assert (w.running, w.rows) == (False, 4)
    text = w.partial_path.read_text()
    assert text.endswith("\n0.100000  0.100000\n0.200000  0.200000\n0.300000  0.300000\n0.400000  0.400000\n")
    assert read_log(w.save()).rows == 4


def test_a_run_whose_disk_fills_exits_non_zero_and_keeps_whole_rows(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    real_open = open
    header = 86  # "% TANK LOG-file" .. the blank line, as the run writes it
    row = len("0.622070  0.623535  0.300000  0.300000\n")
    monkeypatch.setattr(log_module, "open", lambda f, mode, buffering=-1: _FullDisk(
        real_open(f, mode, buffering=buffering), room=header + 10 * row + 17), raising=False)
    out = tmp_path / "full.log"
    code = main(["run", "--duration", "30", "--log", str(out)])
    text = capsys.readouterr().out
    assert code == 1
    assert "No space left on device" in text and "the 10 whole rows written are kept" in text
    data = out.read_bytes()
    assert data.endswith(b"\n") and data.count(b"\n") == 4 + 10
    log = read_log(out)
    assert log.rows == 10 and not any("incomplete" in w for w in log.warnings)


def test_a_read_only_logs_folder_is_refused_before_the_run(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """Found at the start, not at the script's LogOn 600 s into the run (the
    folder is made unwritable by the probe failing: the tests may run as root)."""
    logs = tmp_path / "logs"
    logs.mkdir()
    script = tmp_path / "late.yaml"
    script.write_text("- {at: 0, state: Run}\n- {at: 600, log: on}\n")

    def read_only(*args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(log_module.tempfile, "TemporaryFile", read_only)
    ran: list[float] = []
    monkeypatch.setattr(headless, "run_experiment", lambda engine, scr, duration: ran.append(duration))
    code = main(["run", "--script", str(script), "--duration", "1200", "--log", str(logs / "x.log")])
    err = capsys.readouterr().err
    assert code == 2 and ran == []
    assert f"{logs}: cannot write logs here: Permission denied" in err and err.count("\n") == 1


def test_no_header_only_partial_is_left_when_nothing_was_logged(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    script = tmp_path / "idle.yaml"
    script.write_text("- {at: 0, log: on}\n")  # logging on, but the loop never runs
    assert main(["run", "--script", str(script), "--duration", "5", "--log", str(tmp_path / "x.log")]) == 1
    assert "no log written: nothing to save" in capsys.readouterr().out
    assert sorted(os.listdir(tmp_path)) == ["idle.yaml"]


def par(folder: Path, name: str, u1: float) -> Path:
    """A .par whose input 1 holds `u1`: a run's rows say which run wrote them."""
    from quadtank_tui.core.parameters import PRESET
    from quadtank_tui.files.par import write_par

    return write_par(folder / f"{name}.par", PRESET.with_values({"REFERENCE ONE.Mean": u1}))


def test_log_info_says_a_torn_last_row_was_dropped(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """What a full disk left before this fix (`0.300` of `0.300000`): `log info`
    counts the whole rows and says, on stderr, that the cut one was dropped."""
    torn = tmp_path / "torn.log"
    torn.write_bytes(b"% TANK LOG-file\n% Logged variables: y1 u1   TSamp: 0.1s\n\n"
                     b"0.622070  0.300000\n0.623535  0.300")
    assert main(["log", "info", str(torn)]) == 0
    captured = capsys.readouterr()
    assert "rows       1\n" in captured.out
    assert f"quadtank: warning: {torn}, line 5: incomplete last row dropped (file cut off while writing)" in captured.err


def test_a_failed_save_names_the_log_not_the_partial_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    w = LogWriter(tmp_path / "x.log", ("y1",), 1.0, 10)
    w.append({"y1": 0.5})

    def denied(src: str, dst: str) -> None:
        raise PermissionError(errno.EACCES, "Permission denied", src, dst)

    monkeypatch.setattr(log_module.os, "replace", denied)
    with pytest.raises(PermissionError) as info:
        w.save()
    assert str(info.value) == f"[Errno 13] Permission denied: '{tmp_path / 'x.log'}'"
    monkeypatch.undo()
    assert read_log(w.save()).rows == 1


@pytest.mark.parametrize("kind", ["fifo", "directory"])
def test_a_log_target_that_is_not_a_file_is_refused_at_the_start(
        kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "x.log"
    os.mkfifo(out) if kind == "fifo" else out.mkdir()
    assert main(["run", "--duration", "5", "--log", str(out)]) == 2
    err = capsys.readouterr().err
    what = ("not a regular file (a device, a FIFO or a socket)" if kind == "fifo"
            else f"a folder; --log names the .log to write (e.g. {out / 'run.log'})")
    assert err.startswith(f"quadtank: error: --log {out}: {what}") and err.count("\n") == 1
    assert sorted(os.listdir(tmp_path)) == ["x.log"]


@pytest.mark.parametrize("detach", [False, True], ids=["run", "detach"])
@pytest.mark.parametrize("case", ["device", "folder", "no folder"])
def test_a_log_path_to_a_device_a_folder_or_no_folder_is_refused(
        case: str, detach: bool, tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 41: `--log /dev/null` wrote /dev/null.log, `--log /tmp` /tmp.log, and
    `--log /nonexistent/x.log` created /nonexistent."""
    monkeypatch.setenv("QUADTANK_RUNTIME", str(tmp_path / "rt"))
    target = {"device": Path("/dev/null"), "folder": tmp_path / "logs", "no folder": tmp_path / "none" / "x.log"}[case]
    (tmp_path / "logs").mkdir()
    before = sorted(os.listdir(tmp_path))
    args = ["run", "--duration", "5", "--log", str(target)] + (["--realtime", "--detach"] if detach else [])
    assert main(args) == 2
    err = capsys.readouterr().err.splitlines()
    said = {"device": f"--log {target}: not a regular file (a device, a FIFO or a socket)",
            "folder": f"--log {target}: a folder; --log names the .log to write",
            "no folder": f"--log {target}: the folder {target.parent} does not exist"}[case]
    assert [line for line in err if "warning" not in line] == [
        line for line in err if line.startswith(f"quadtank: error: {said}")], err
    assert any(line.startswith(f"quadtank: error: {said}") for line in err), err
    assert sorted(os.listdir(tmp_path)) == before and not Path("/dev/null.log").exists()
    assert not (tmp_path / "logs.log").exists() and not (tmp_path / "none").exists()


def _disk_with_room(monkeypatch: pytest.MonkeyPatch, rows: int) -> None:
    """The log's file on a disk that takes its header and `rows` rows of y1 y2 u1 u2."""
    real_open = open
    header = 86
    row = len("0.622070  0.623535  0.300000  0.300000\n")
    monkeypatch.setattr(log_module, "open", lambda f, mode, buffering=-1: _FullDisk(
        real_open(f, mode, buffering=buffering), room=header + rows * row + 17), raising=False)


def test_a_full_disk_at_x1000_is_said_when_it_happens_and_ends_the_run(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 41: a Simul run at x1000 whose disk filled went on to its end (here
    3000 s of loop time, 3 s of wall) and only then said LOG FAULT.  Now the line
    comes on stderr at the sample the fault was taken in, and the run ends there,
    its rows kept and the summary over the time it ran."""
    _disk_with_room(monkeypatch, 50)
    out = tmp_path / "full.log"
    assert main(["run", "--speed", "1000", "--duration", "3000", "--log", str(out)]) == 1
    captured = capsys.readouterr()
    said = [line for line in captured.err.splitlines() if "LOG FAULT" in line]
    assert len(said) == 1 and said[0].startswith("quadtank: LOG FAULT at t = "), captured.err
    assert said[0].endswith("cannot write (No space left on device): logging stopped; the 50 whole rows "
                            "written are kept; the run stops here")
    at = float(said[0].split("t = ")[1].split(" s:")[0])
    assert 5.0 <= at < 100.0  # the 50 rows are 5 s; the fault is taken in within a few file batches
    summary = captured.out.splitlines()
    assert summary[0].startswith(f"ran {at:g} s: ")
    assert "LOG FAULT  cannot write (No space left on device): logging stopped; the 50 whole rows written are " \
        "kept" in summary
    assert read_log(out).rows == 50


def test_a_full_disk_is_said_on_the_way_out_by_a_signal(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """Stopped by SIGTERM (Terminated) or Ctrl-C after the disk filled, the run said
    no LOG FAULT at all: the summary that says it is not printed on that way out."""
    from quadtank_tui.commands.run import Terminated

    _disk_with_room(monkeypatch, 20)

    def until_the_signal(engine, script, duration, watch=None):
        engine.run_for(10.0)  # 100 rows: the disk fills at row 20
        raise Terminated(15)  # what the SIGTERM handler raises, before the next sample's watch

    monkeypatch.setattr(headless, "run_experiment", until_the_signal)
    out = tmp_path / "full.log"
    assert main(["run", "--duration", "60", "--log", str(out)]) == 143
    err = capsys.readouterr().err.splitlines()
    assert err[-2:] == ["quadtank: LOG FAULT  cannot write (No space left on device): logging stopped; the 20 whole "
                        "rows written are kept", "quadtank: stopped by SIGTERM"], err
