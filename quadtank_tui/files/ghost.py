"""A saved `.log` as trend signals, to draw behind the live ones (a "ghost" run).

The trends name their signals as the engine's history does (y1..y4, u1, u2,
ref1, ref2); a `.log` calls the references r1, r2 and may or may not have a
time column.  This turns one into the other, so the UI never parses a file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from quadtank_tui.files.log_reader import LogFileError, read_log

#: The log's column name for each trend signal that differs.
_LOG_NAMES = {"ref1": "r1", "ref2": "r2"}
#: The signals a trend can draw.
TREND_SIGNALS = ("y1", "y2", "y3", "y4", "u1", "u2", "ref1", "ref2")


@dataclass(frozen=True, eq=False)
class LoggedRun:
    """A log's signals: `t` in seconds from its first row (LogOn), normalized
    values by trend name (only the logged ones).  Compared by identity."""

    name: str
    t: np.ndarray
    signals: Mapping[str, np.ndarray] = field(default_factory=dict)


def load_run(path: Path | str) -> LoggedRun:
    """Read `path`; LogFileError (file, line, reason) if it cannot be drawn."""
    path = Path(path)
    log = read_log(path)
    if "t" in log.variables:
        t = log["t"] - log["t"][0] if log.rows else log["t"]
    elif log.tsamp is not None:
        t = np.arange(log.rows) * log.tsamp
    else:
        raise LogFileError(str(path), "no t column and no TSamp in the header: its rows have no times")
    signals = {name: np.array(log[_LOG_NAMES.get(name, name)], dtype=float)
               for name in TREND_SIGNALS if _LOG_NAMES.get(name, name) in log.variables}
    if not signals:
        raise LogFileError(str(path), f"none of the trends' signals is logged (it has {' '.join(log.variables)})")
    if log.rows == 0:
        raise LogFileError(str(path), "no rows")
    return LoggedRun(path.name, np.array(t, dtype=float), signals)


def logs_newest_first(folder: Path | str) -> list[Path]:
    """The `.log` files of `folder`, the most recently written first (the
    ghost's default is the first)."""
    try:
        logs = [p for p in Path(folder).glob("*.log") if p.is_file()]
        return sorted(logs, key=lambda p: (p.stat().st_mtime, p.name), reverse=True)
    except OSError:
        return []
