"""The `.log` "Created on:" stamp (issue 17.9): a TUI run at a speed-up stamps the
wall clock at LogOn; a run given an epoch (headless virtual runs) stamps epoch +
process time, the same bytes every time."""

from __future__ import annotations

from datetime import datetime, timedelta
from pathlib import Path

from quadtank_tui.engine import commands as c
from quadtank_tui.engine.runner import build_engine
from quadtank_tui.files.log_reader import read_log
from quadtank_tui.files.shipped import write_shipped


def _log_after(tmp_path: Path, seconds: float, **kwargs: object) -> datetime | None:
    write_shipped(tmp_path / "params")
    engine = build_engine(clock="manual", params_dir=tmp_path / "params", logs_dir=tmp_path / "logs",
                          **kwargs)  # type: ignore[arg-type]
    engine.submit(c.SetState("Run"))
    engine.run_for(seconds)  # ten minutes of process time in no wall time
    assert engine.submit(c.LogOn()).result().ok
    engine.run_for(1.0)
    for command in (c.LogOff(), c.LogSave("x")):
        assert engine.submit(command).result().ok
    return read_log(tmp_path / "logs" / "x.log").created


def test_a_run_without_an_epoch_stamps_the_wall_clock_at_logon(tmp_path: Path) -> None:
    before = datetime.now().replace(microsecond=0)
    created = _log_after(tmp_path, 600.0)
    after = datetime.now()
    assert created is not None and before <= created <= after


def test_a_run_with_an_epoch_stamps_epoch_plus_process_time(tmp_path: Path) -> None:
    epoch = datetime(2000, 1, 1, 0, 0, 0)
    assert _log_after(tmp_path, 600.0, epoch=epoch) == epoch + timedelta(seconds=600)
