"""The Logging window's state in the loop: LogOn .. LogOff .. Save / Discard (M8).

Rows go to the partial file as they are taken (files/log_writer.py), so nothing logged is
lost if the program dies; Save moves it to `logs/<name>.log`.  The loop owns one
session and hands it a row per sample while it is on.  The partial file is this
run's alone (locked, and named apart from another run's of the same name), so two
runs logging under one name in one folder never mix their rows.

The disk is not on the sampling path: every operation on the file (LogOn's header,
each row, LogOff, Save, Discard) goes to the loop's :class:`FileWorker` in order, and
the session keeps the loop's view (logging or not, rows taken, saved or not) itself.
A write that fails there (disk full) is noted and raised at the loop's next
:meth:`LogSession.check`, with the writer's message: the loop faults, pumps to 0.
"""

from __future__ import annotations

import contextlib
from concurrent.futures import Future
from datetime import datetime
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

from quadtank_tui.core.parameters import LoggingSettings
from quadtank_tui.engine.filework import FileWorker
from quadtank_tui.engine.snapshot import LogStatus
from quadtank_tui.files.log_writer import LogFileError, LogWriter, log_path
from quadtank_tui.files.names import check_file_name


class LogRefused(ValueError):
    """A logging command that cannot be honoured now; the message says why."""


class LogExists(LogRefused):
    """Save refused because the target exists (and may not be replaced)."""


class LogSession:
    """logs_dir : where logs are saved (and the partial file lives);
    now : the "Created on:" stamp (injected: virtual runs are reproducible);
    files : where the file operations run (default: at once, on the caller's thread).

    The loop's side (`running`, `rows`, :meth:`status`) changes at once, in command
    order; the writer (`_writer`) is touched only by the file operations.
    """

    def __init__(self, logs_dir: Path, now: Callable[[], datetime], files: FileWorker | None = None) -> None:
        self.logs_dir = logs_dir
        self._now = now
        self.files = files if files is not None else FileWorker()
        self._writer: LogWriter | None = None  # the file operations' own
        self._path: Path | None = None  # the log in hand (None: none since the last Discard)
        self._active = False
        self._rows = 0
        self._points = 0
        self._t0 = 0.0
        self._unsaved = False
        self._saved = ""
        self._error: str | None = None
        self._failure: tuple[Exception, int] | None = None  # set by a failed write, see check()
        #: Rows of this log that came late (each noted in the file), see `late`.
        self.late_rows = 0
        self._batched = self._run_writes  # bound once, not at every row (compared equal either way by the batch)

    @property
    def running(self) -> bool:
        return self._active

    @property
    def started_at(self) -> float:
        """Process time of the last LogOn: the log's `t` column counts from it."""
        return self._t0

    @property
    def rows(self) -> int:
        """Rows of the log (once the writes handed out are done: a run's end)."""
        self._settle()
        return self._rows

    @property
    def error(self) -> str | None:
        """Why the current log stopped early (a failed write), or None (once the
        writes handed out are done: a run's end)."""
        self._settle()
        return self._error

    @property
    def failed(self) -> str | None:
        """Why the log stopped early, as far as the loop has taken it in (a failed
        write is taken in at the next sample): no wait for the file thread, so it
        may be asked every sample."""
        return self._error

    def _settle(self) -> None:
        """Wait for the file operations, and take in a failed write's outcome."""
        self.files.drain()
        failure = self._failure
        try:
            self.check()
        except Exception:  # noqa: BLE001 - now in rows and error; kept for the loop's next step
            self._failure = failure

    def status(self, settings: LoggingSettings) -> LogStatus:
        path = self._path
        return LogStatus(
            active=self._active, rows=0 if path is None else self._rows,
            points=settings.points if path is None else self._points, unsaved=self._unsaved,
            file=settings.log_file, saved_path=self._saved,
            started_as="" if path is None or not self._unsaved else path.name.removesuffix(".log"),
        )

    def check(self) -> None:
        """Raise what a write failed with (LogFileError: disk full), once; logging has
        stopped then, and `rows` is the whole rows the file keeps."""
        failure = self._failure
        if failure is None:
            return
        self._failure = None
        exc, kept = failure
        self._active = False
        self._rows = kept
        self._error = _reason(exc)
        raise exc

    def on(self, settings: LoggingSettings, tsamp: float, t: float, points: int | None = None) -> Future[tuple[str, ...]]:
        """LogOn: a new log from process time `t` of `points` rows (default: the
        Logging window's Points); the Future has the warnings, or why it could not start."""
        points = settings.points if points is None else points
        path = log_path(self.logs_dir, settings.log_file)
        keep_old = self._path is not None and self._unsaved
        created = self._now()
        self._path, self._active, self._rows, self._points = path, True, 0, points
        self._t0 = t
        self._unsaved = False
        self._error, self._failure = None, None
        self.late_rows = 0

        def open_log() -> tuple[str, ...]:
            try:
                return start()
            except BaseException:  # refused: nothing is logging (before the Future says so)
                self._active = False
                self._path = None
                raise

        def start() -> tuple[str, ...]:
            warnings: list[str] = []
            old, self._writer = self._writer, None
            if old is not None and keep_old:
                rows = old.rows
                kept = old.keep()  # under any name: never left as a silent .partial
                warnings.append(f"the unsaved log ({rows} rows) was kept as {kept}")
            if old is not None:
                old.close()
            self.logs_dir.mkdir(parents=True, exist_ok=True)
            self._writer = LogWriter(path, settings.variables, tsamp, points, created=created)
            warnings.extend(f"an unsaved earlier log was kept as {p}" for p in self._writer.recovered)
            return tuple(warnings)

        return self.files.submit(open_log)

    def row(self, t: float, y: Sequence[float], u: Sequence[float], r: Sequence[float]) -> None:
        """One sample at process time `t` (the `t` column counts from LogOn)."""
        assert self._active
        self._unsaved = True  # before: a failed write still leaves the rows before it
        self._rows += 1
        if self._rows >= self._points:
            self._active = False  # the writer stops by itself at its last point
        self._write(LogWriter.append_row, (t - self._t0, y[0], y[1], y[2], y[3], u[0], u[1], r[0], r[1]))

    def late(self, gap: float, tsamp: float) -> None:
        """The next row was sampled `gap` s after the previous one, not `tsamp` (a
        real process whose samples came late): the log says so before the row."""
        assert self._active
        if self._rows == 0:
            return  # the first row: there is no previous one to be late after
        self._write(LogWriter.comment, f"late: the next row was sampled {gap:.6g} s after the previous one, "
                    f"not TSamp {tsamp:g} s")
        self.late_rows += 1

    def comment(self, t: float, text: str) -> None:
        """A `%` line stamped with the log's time (s since LogOn), if logging is on."""
        if self._active:
            self._write(LogWriter.comment, f"t = {t - self._t0:g} s: {text}")

    def _write(self, op: Callable[[LogWriter, Any], object], arg: object) -> None:
        """Hand a row or a comment to the writer; a failure is raised by check()
        (at once when the file operations run inline)."""
        if self.files.batches:
            self.files.submit_batched(self._batched, (op, arg))
        else:  # inline, as submit() would run it, without a Future per row
            try:
                self._run_write(op, arg)
            except Exception:  # noqa: BLE001 - kept in _failure: check() raises it
                pass
        self.check()

    def _run_writes(self, ops: list[tuple[Callable[[LogWriter, Any], object], object]]) -> None:
        """Several of _write's operations on the file thread, handed to the OS in one
        write; a failure is kept for check() as _run_write keeps it."""
        writer = self._writer
        if writer is not None:
            with self._keeping_failure(writer), writer.held():
                for op, arg in ops:
                    op(writer, arg)

    def _run_write(self, op: Callable[[LogWriter, Any], object], arg: object) -> None:
        """One of _write's operations, as the file worker runs it."""
        writer = self._writer
        if writer is not None:
            with self._keeping_failure(writer):
                op(writer, arg)

    @contextlib.contextmanager
    def _keeping_failure(self, writer: LogWriter) -> Iterator[None]:
        """A failure of the writes inside is kept for check() (the first one) and
        raised on to the worker."""
        try:
            yield
        except Exception as exc:
            if self._failure is None:
                self._failure = (exc, writer.rows)
            raise

    def off(self) -> Future[None]:
        if not self._active:
            raise LogRefused("logging is not on")
        return self.stop()

    def stop(self) -> Future[None]:
        """Stop taking rows (LogOff, Reset); the rows stay in the partial file."""
        self._active = False
        return self.files.submit(self._on_writer, LogWriter.stop)

    def close(self) -> Future[None]:
        """Exit (or a new LogOn): stop; a partial file without rows is removed,
        one with rows stays for the next LogOn of its name to recover."""
        self._active = False
        return self.files.submit(self._on_writer, LogWriter.close)

    def _on_writer(self, method: Callable[[LogWriter], object]) -> None:
        if self._writer is not None:
            method(self._writer)

    def save_later(self, name: str, overwrite: bool | Callable[[Path], bool]) -> Future[Path]:
        """Save under `name`; an existing file is replaced only if `overwrite` is
        True or says so for it (LogExists otherwise).  Nothing logged: LogRefused,
        and the empty partial file is removed.  The Future has the path."""
        if self._path is None or not self._unsaved or self._rows == 0:
            if self._path is not None and self._rows == 0:
                self.discard()
            raise LogRefused("nothing to save: no rows logged since the last Save")
        check_file_name(name.removesuffix(".log"), "LogFile")
        target = log_path(self.logs_dir, name)
        saved_before = self._saved
        self._active, self._unsaved, self._saved = False, False, str(target)

        def save() -> Path:
            try:
                if self._writer is None:
                    raise LogRefused("nothing to save: the log could not be started")
                try:
                    return self._writer.save(target, replace=overwrite)
                except FileExistsError:
                    raise LogExists(f"{target} exists (save again to overwrite)") from None
            except BaseException:  # still unsaved (before the Future says so): Save again, or Discard
                self._unsaved, self._saved = True, saved_before
                raise

        return self.files.submit(save)

    def save(self, name: str, overwrite: bool | Callable[[Path], bool]) -> Path:
        """:meth:`save_later`, waited for (a headless run's end)."""
        return self.save_later(name, overwrite).result()

    def discard(self) -> Future[None]:
        self._active, self._unsaved, self._path, self._rows = False, False, None, 0

        def discard() -> None:
            if self._writer is not None:
                self._writer.discard()
            self._writer = None

        return self.files.submit(discard)


def _reason(exc: Exception) -> str:
    """A failed write's message without the file name (the writer's `error`)."""
    return exc.reason if isinstance(exc, LogFileError) else f"{type(exc).__name__}: {exc}"
