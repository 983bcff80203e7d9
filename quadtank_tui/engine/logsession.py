"""The Logging window's state in the loop: LogOn .. LogOff .. Save / Discard (M8).

Rows go to the partial file as they are taken (files/log.py), so nothing logged is
lost if the program dies; Save moves it to `logs/<name>.log`.  The loop owns one
session and hands it a row per sample while it is on.  The partial file is this
run's alone (locked, and named apart from another run's of the same name), so two
runs logging under one name in one folder never mix their rows.
"""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import Callable, Sequence

from quadtank_tui.core.parameters import LoggingSettings
from quadtank_tui.engine.snapshot import LogStatus
from quadtank_tui.files.log import LogWriter, log_path
from quadtank_tui.files.names import check_file_name


class LogRefused(ValueError):
    """A logging command that cannot be honoured now; the message says why."""


class LogExists(LogRefused):
    """Save refused because the target exists (and may not be replaced)."""


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
        #: Rows of this log that came late (each noted in the file), see `late`.
        self.late_rows = 0

    @property
    def running(self) -> bool:
        return self._writer is not None and self._writer.running

    @property
    def rows(self) -> int:
        return 0 if self._writer is None else self._writer.rows

    @property
    def error(self) -> str | None:
        """Why the current log stopped early (a failed write), or None."""
        return None if self._writer is None else self._writer.error

    def status(self, settings: LoggingSettings) -> LogStatus:
        w = self._writer
        return LogStatus(
            active=self.running, rows=0 if w is None else w.rows,
            points=settings.points if w is None else w.points, unsaved=self._unsaved,
            file=settings.log_file, saved_path=self._saved,
            started_as="" if w is None or not self._unsaved else w.path.name.removesuffix(".log"),
        )

    def on(self, settings: LoggingSettings, tsamp: float, t: float, points: int | None = None) -> tuple[str, ...]:
        """LogOn: a new log from process time `t` of `points` rows (default: the
        Logging window's Points); returns warnings."""
        self.logs_dir.mkdir(parents=True, exist_ok=True)
        warnings: list[str] = []
        if self._writer is not None and self._unsaved:
            rows = self._writer.rows
            kept = self._writer.keep()  # under any name: never left as a silent .partial
            warnings.append(f"the unsaved log ({rows} rows) was kept as {kept}")
        self.close()
        self._writer = LogWriter(log_path(self.logs_dir, settings.log_file), settings.variables, tsamp,
                                 settings.points if points is None else points, created=self._now())
        self._t0 = t
        self._unsaved = False
        self.late_rows = 0
        warnings.extend(f"an unsaved earlier log was kept as {p}" for p in self._writer.recovered)
        return tuple(warnings)

    def row(self, t: float, y: Sequence[float], u: Sequence[float], r: Sequence[float]) -> None:
        """One sample at process time `t` (the `t` column counts from LogOn)."""
        assert self._writer is not None
        self._unsaved = True  # before: a failed write still leaves the rows before it
        self._writer.append({
            "t": t - self._t0, "y1": y[0], "y2": y[1], "y3": y[2], "y4": y[3],
            "u1": u[0], "u2": u[1], "r1": r[0], "r2": r[1],
        })

    def late(self, gap: float, tsamp: float) -> None:
        """The next row was sampled `gap` s after the previous one, not `tsamp` (a
        real process whose samples came late): the log says so before the row."""
        assert self._writer is not None
        if self._writer.rows == 0:
            return  # the first row: there is no previous one to be late after
        self._writer.comment(f"late: the next row was sampled {gap:.6g} s after the previous one, "
                              f"not TSamp {tsamp:g} s")
        self.late_rows += 1

    def comment(self, t: float, text: str) -> None:
        """A `%` line stamped with the log's time (s since LogOn), if logging is on."""
        if self.running:
            assert self._writer is not None
            self._writer.comment(f"t = {t - self._t0:g} s: {text}")

    def off(self) -> None:
        if not self.running:
            raise LogRefused("logging is not on")
        self.stop()

    def stop(self) -> None:
        """Stop taking rows (LogOff, Reset); the rows stay in the partial file."""
        if self._writer is not None:
            self._writer.stop()

    def close(self) -> None:
        """Exit (or a new LogOn): stop; a partial file without rows is removed,
        one with rows stays for the next LogOn of its name to recover."""
        if self._writer is not None:
            self._writer.close()

    def save(self, name: str, overwrite: bool | Callable[[Path], bool]) -> Path:
        """Save under `name`; an existing file is replaced only if `overwrite` is
        True or says so for it (LogExists otherwise).  Nothing logged: LogRefused,
        and the empty partial file is removed."""
        if self._writer is None or not self._unsaved or self._writer.rows == 0:
            if self._writer is not None and self._writer.rows == 0:
                self.discard()
            raise LogRefused("nothing to save: no rows logged since the last Save")
        check_file_name(name.removesuffix(".log"), "LogFile")
        target = log_path(self.logs_dir, name)
        try:
            saved = self._writer.save(target, replace=overwrite)
        except FileExistsError:
            raise LogExists(f"{target} exists (save again to overwrite)") from None
        self._saved = str(saved)
        self._unsaved = False
        return saved

    def discard(self) -> None:
        if self._writer is not None:
            self._writer.discard()
        self._writer = None
        self._unsaved = False
