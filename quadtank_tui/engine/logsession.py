"""The Logging window's state in the loop: LogOn .. LogOff .. Save / Discard (M8).

Rows go to the partial file as they are taken (files/log.py), so nothing logged is
lost if the program dies; Save moves it to `logs/<name>.log`.  The loop owns one
session and hands it a row per sample while it is on.
"""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import Callable, Sequence

from quadtank_tui.core.parameters import LoggingSettings, check_file_name
from quadtank_tui.engine.snapshot import LogStatus
from quadtank_tui.files.log import LogWriter, log_path


class LogRefused(ValueError):
    """A logging command that cannot be honoured now; the message says why."""


class LogSession:
    """logs_dir : where logs are saved (and the partial file lives);
    now : the "Created on:" stamp (injected: virtual runs are reproducible)."""

    def __init__(self, logs_dir: Path, now: Callable[[], datetime]) -> None:
        self.logs_dir = logs_dir
        self._now = now
        self._writer: LogWriter | None = None
        self._t0 = 0.0
        self._unsaved = False
        self._saved = ""

    @property
    def running(self) -> bool:
        return self._writer is not None and self._writer.running

    def status(self, settings: LoggingSettings) -> LogStatus:
        w = self._writer
        return LogStatus(
            active=self.running, rows=0 if w is None else w.rows,
            points=settings.points if w is None else w.points, unsaved=self._unsaved,
            file=settings.log_file, saved_path=self._saved,
            started_as="" if w is None or not self._unsaved else w.path.name.removesuffix(".log"),
        )

    def on(self, settings: LoggingSettings, tsamp: float, t: float) -> tuple[str, ...]:
        """LogOn: a new log from process time `t`; returns warnings."""
        self.logs_dir.mkdir(parents=True, exist_ok=True)
        warnings: list[str] = []
        if self._writer is not None and self._unsaved:
            rows = self._writer.rows
            kept = self._writer.keep()  # under any name: never left as a silent .partial
            if kept is not None:
                warnings.append(f"the unsaved log ({rows} rows) was kept as {kept}")
        self.stop()
        self._writer = LogWriter(log_path(self.logs_dir, settings.log_file), settings.variables, tsamp,
                                 settings.points, created=self._now())
        self._t0 = t
        self._unsaved = False
        if self._writer.recovered is not None:
            warnings.append(f"an unsaved earlier log was kept as {self._writer.recovered}")
        return tuple(warnings)

    def row(self, t: float, y: Sequence[float], u: Sequence[float], r: Sequence[float]) -> None:
        """One sample at process time `t` (the `t` column counts from LogOn)."""
        assert self._writer is not None
        self._writer.append({
            "t": t - self._t0, "y1": y[0], "y2": y[1], "y3": y[2], "y4": y[3],
            "u1": u[0], "u2": u[1], "r1": r[0], "r2": r[1],
        })
        self._unsaved = True

    def off(self) -> None:
        if not self.running:
            raise LogRefused("logging is not on")
        self.stop()

    def stop(self) -> None:
        """Stop taking rows (LogOff, Reset, Exit); the rows stay in the partial file."""
        if self._writer is not None:
            self._writer.stop()

    def save(self, name: str, overwrite: bool) -> Path:
        if self._writer is None or not self._unsaved:
            raise LogRefused("nothing to save: no rows logged since the last Save")
        check_file_name(name.removesuffix(".log"), "LogFile")
        target = log_path(self.logs_dir, name)
        if target.exists() and not overwrite:
            raise LogRefused(f"{target} exists (save again to overwrite)")
        saved = self._writer.save(target)
        self._saved = str(saved)
        self._unsaved = False
        return saved

    def discard(self) -> None:
        if self._writer is not None:
            self._writer.discard()
        self._writer = None
        self._unsaved = False
