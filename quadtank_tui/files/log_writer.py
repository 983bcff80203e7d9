"""Writing `.log` data files: the original's layout, as a stream (the reader is log_reader.py).

The layout (thesis 5.3)::

    % TANK LOG-file
    % Created on: Jun 20 00:30:50 1997
    % Logged variables: y1 y2 u1 u2   TSamp: 1s

    0.622070  0.623535  0.300000  0.300000

The format's pieces (the header line, the `%f` row, the suffix) are defined
here, where the layout is written; the reader imports them.

:class:`LogWriter` is the Logging window's LogOn/LogOff/Save.  Rows go to a
partial file (`<name>.log.partial`) as they come, so a crash loses nothing that was
flushed, and that partial file is itself a valid log (the header is written and
synced first; each flush is whole lines, cut back if the write fails).  The
partial file is locked by its writer, so another run logging under the same name
takes `<name>.log.2.partial` instead of mixing rows into it.  Save renames it to
the final `.log` atomically.  Clock and `Created on:` stamp are injected for tests.
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import sys
import tempfile
import time
from datetime import datetime
from decimal import Decimal
from operator import itemgetter
from pathlib import Path
from typing import Callable, Iterator, Mapping, Sequence


try:  # POSIX; elsewhere the unique partial names alone keep runs apart
    import fcntl
except ImportError:  # pragma: no cover
    fcntl = None  # type: ignore[assignment]  # no module off POSIX: users test for None

from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.files.atomic import atomic_write_bytes, fsync_dir
from quadtank_tui.files.names import LOG_VARIABLES, check_variables
from quadtank_tui.files.stamp import format_stamp

HEADER = "% TANK LOG-file"
SUFFIX = ".log"
PARTIAL_SUFFIX = ".partial"
COLUMN_SEPARATOR = "  "

class LogFileError(ValueError):
    """A `.log` refused (reading) or a request the writer cannot honour."""

    def __init__(self, file: str, reason: str, line: int | None = None) -> None:
        super().__init__(f"{file}{'' if line is None else f', line {line}'}: {reason}")
        self.file = file
        self.line = line
        self.reason = reason


# --- format -------------------------------------------------------------------------------

def format_tsamp(seconds: float) -> str:
    """The sampling time as the header writes it: the shortest exact decimal
    ("1", "0.1", "0.05"), never an exponent."""
    if not (isinstance(seconds, (int, float)) and math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"TSamp must be a positive number of seconds, got {seconds!r}")
    return format(Decimal(repr(float(seconds))).normalize(), "f")


def format_header(variables: Sequence[str], tsamp: float, created: datetime) -> str:
    """Header lines and the blank line before the data."""
    return (
        f"{HEADER}\n"
        f"% Created on: {format_stamp(created)}\n"
        f"% Logged variables: {' '.join(variables)}   TSamp: {format_tsamp(tsamp)}s\n"
        "\n"
    )


def format_row(values: Sequence[float]) -> str:
    """One sample: `%f` values separated by two spaces."""
    return COLUMN_SEPARATOR.join(_f(v) for v in values) + "\n"


def _f(value: float) -> str:
    """`%f`, except that a value that rounds to zero is written "0.000000", never
    "-0.000000" (a tiny negative input or -0.0 would otherwise show a sign)."""
    text = "%f" % value
    return "0.000000" if text == "-0.000000" else text


def log_path(folder: Path | str, name: str) -> Path:
    """`folder/name.log` (`.log` added unless the name already has it)."""
    return Path(folder) / (name if name.endswith(SUFFIX) else name + SUFFIX)


# --- writing ------------------------------------------------------------------------------

class LogWriter:
    """LogOn .. LogOff .. Save for one log.

    Creating the writer is LogOn: it claims a partial file next to the final one,
    `<name>.log.partial` (or `<name>.log.2.partial`, ... while another run is
    writing one of that name), holds an exclusive lock on it until Save or
    Discard (or the process ends), and writes the header.  Then :meth:`append`
    once per sample (the values by variable name; extra names are ignored).
    Logging stops by itself after `points` rows, or at :meth:`stop` (LogOff).
    :meth:`save` renames the partial file to the final `.log`; :meth:`discard`
    removes it.  An unlocked partial file with rows at LogOn is the unsaved log of
    a run that died: it is kept as `<name>-recovered.log`, see `recovered`.

    :meth:`append_row` takes a sample as a tuple in :data:`LOG_VARIABLES` order
    instead, the loop's way: the same bytes, a quarter of the cost.

    Rows are handed to the OS every `flush_rows` rows (default: every row, a
    few dozen bytes per sample) and fsynced at most every `fsync_interval` s of
    `clock` time, so a killed process loses nothing and a power cut at most about
    a second.  A write that fails (disk full) is cut back to the last whole row
    and stops the log: the file never ends in a torn row.
    """

    def __init__(
        self,
        path: Path | str,
        variables: Sequence[str],
        tsamp: float,
        points: int,
        *,
        created: datetime | None = None,
        flush_rows: int = 1,
        fsync_interval: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        try:
            self.variables = check_variables("variables", variables)
        except ParameterError as exc:
            raise LogFileError(str(path), exc.reason) from None
        if isinstance(points, bool) or not isinstance(points, int) or points < 1:
            raise LogFileError(str(path), f"points must be a whole number >= 1, got {points!r}")
        if flush_rows < 1:
            raise LogFileError(str(path), f"flush_rows must be >= 1, got {flush_rows}")
        header = format_header(self.variables, tsamp, created or datetime.now()).encode("ascii")
        # append_row's way: the logged columns picked out of a full row (in C), one `%` format.
        columns = [LOG_VARIABLES.index(name) for name in self.variables]
        pick = itemgetter(*columns)
        self._pick: Callable[[Sequence[float]], tuple[float, ...]] = (
            pick if len(columns) > 1 else lambda row: (pick(row),))
        self._row_format = COLUMN_SEPARATOR.join(["%f"] * len(self.variables)) + "\n"
        self.path = Path(path)
        self.tsamp = float(tsamp)
        self.points = points
        self.rows = 0
        self._flush_rows = flush_rows
        self._fsync_interval = fsync_interval
        self._clock = clock
        self._pending: list[str] = []
        #: Where earlier runs' unsaved partial files were moved, if there were any.
        self.recovered: tuple[Path, ...] = ()
        self._writing = False
        #: Why logging stopped early (a failed write: disk full), or None.
        self.error: str | None = None
        fd, self.partial_path, self.recovered = _claim_partial(self.path)
        self._file = open(fd, "wb", buffering=0)  # holds the lock until closed
        self._size = 0  # bytes of whole lines in the file
        self._kept = 0  # whole lines of the last write that failed part-way
        self._rows_written = 0
        try:
            self._write(header)
            os.fsync(fd)
        except OSError as exc:
            self.discard()
            raise LogFileError(str(self.path), f"cannot write: {exc.strerror or exc}") from None
        self._writing = True
        self._last_sync = clock()

    @property
    def running(self) -> bool:
        """True between LogOn and LogOff (or the last point, or a failed write)."""
        return self._writing

    @property
    def progress(self) -> float:
        """Fraction of the points collected, 0..1 (the Logging window's bar)."""
        return self.rows / self.points

    def append(self, values: Mapping[str, float]) -> bool:
        """Log one sample; False (and nothing written) once logging has stopped."""
        if not self.running:
            return False
        try:
            row = [float(values[name]) for name in self.variables]
        except KeyError as exc:
            raise LogFileError(str(self.path), f"sample has no value for {exc.args[0]!r}") from None
        bad = [n for n, v in zip(self.variables, row) if not math.isfinite(v)]
        if bad:
            raise LogFileError(str(self.path), f"not a finite number: {', '.join(bad)}")
        self._take(format_row(row))
        return True

    def append_row(self, row: Sequence[float]) -> bool:
        """Log one sample given as floats in :data:`LOG_VARIABLES` order: as
        :meth:`append` with those names, byte for byte, without a mapping built
        and formatted value by value (the loop logs every sample, x1000 at 50 ms
        is 20,000 rows a second)."""
        if not self._writing:
            return False
        line = self._row_format % self._pick(row)
        # %f writes digits, '.', '-' and spaces; an 'n' is a nan or an inf, which
        # append refuses, and "-0.000000" is what _f writes unsigned: append's way.
        if "n" in line or "-0.000000" in line:
            return self.append(dict(zip(LOG_VARIABLES, row)))
        self._take(line)
        return True

    def _take(self, line: str) -> None:
        """A formatted row: pending, handed to the OS every `flush_rows`, the last point stops."""
        self._pending.append(line)
        self.rows += 1
        if len(self._pending) >= self._flush_rows or self.rows >= self.points:
            self.flush()
        if self.rows >= self.points:
            self.stop()

    def comment(self, text: str) -> bool:
        """A `%` line between the rows (an event: a fault switched on); readers skip it.
        False once logging has stopped."""
        if not self.running:
            return False
        line = " ".join(str(text).split())
        self._pending.append(f"% {line}\n")
        self.flush()
        return True

    @contextlib.contextmanager
    def held(self) -> Iterator[None]:
        """The rows taken inside go to the OS together, in one write at the end (a
        batch of rows from the loop's file thread), not one write a row."""
        every = self._flush_rows
        self._flush_rows = sys.maxsize
        try:
            yield
        finally:
            self._flush_rows = every
            self.flush()

    def flush(self) -> None:
        """Hand the pending rows to the OS in one write; fsync if a second passed.
        A failed write (disk full) is cut back to the last whole row, logging
        stops, and LogFileError says how many rows the file keeps."""
        if not self._writing:
            return
        try:
            if self._pending:
                data = "".join(self._pending).encode("ascii")
                self._write(data)
                self._rows_written += len(self._pending)
                self._pending.clear()
            now = self._clock()
            if now - self._last_sync >= self._fsync_interval:
                os.fsync(self._file.fileno())
                self._last_sync = now
        except OSError as exc:
            self._writing = False
            self._rows_written += self._kept  # the whole lines the disk took, of a batch
            self._pending.clear()
            self.rows = self._rows_written
            self.error = (f"cannot write ({exc.strerror or exc}): logging stopped; "
                          f"the {self.rows} whole rows written are kept")
            raise LogFileError(str(self.path), self.error) from None

    def _write(self, data: bytes) -> None:
        """Append `data` (whole lines); a write that fails part-way keeps the whole
        lines written before it (`_kept`, of a batch of rows: those the disk took)
        and cuts the rest off, so the file never ends in a torn line."""
        view = memoryview(data)
        written = 0
        self._kept = 0
        try:
            while written < len(data):
                written += self._file.write(view[written:])
        except OSError:
            whole = data.rfind(b"\n", 0, written) + 1
            try:
                os.ftruncate(self._file.fileno(), self._size + whole)
            except OSError:
                whole = 0  # cut back as far as it goes: the size the file had
                try:
                    os.ftruncate(self._file.fileno(), self._size)
                except OSError:
                    pass
            self._size += whole
            self._kept = data.count(b"\n", 0, whole)
            raise
        self._size += len(data)

    def stop(self) -> None:
        """LogOff: write and sync what is pending; the partial file stays locked
        (this run's) until Save or Discard."""
        if not self._writing:
            return
        self._last_sync = -math.inf
        try:
            self.flush()
        finally:
            self._writing = False

    def save(self, path: Path | str | None = None, *, replace: bool | Callable[[Path], bool] = True) -> Path:
        """Stop if running, then move the partial file to `path` (default: the
        path given at LogOn) atomically; returns the final path.  An existing
        `path` is replaced only if `replace` is True or says so for it (decided
        under a lock on the folder, so two savers cannot both take one name);
        otherwise FileExistsError, and the partial file stays."""
        self.stop()
        target = Path(path) if path is not None else self.path
        with _folder_lock(target.parent):
            if os.path.lexists(target) and not (replace(target) if callable(replace) else replace):
                raise FileExistsError(errno.EEXIST, "exists", str(target))
            try:
                os.replace(self.partial_path, target)
            except OSError as exc:
                if exc.errno != errno.EXDEV:  # name the log, not the partial file
                    raise type(exc)(exc.errno, exc.strerror or str(exc), str(target)) from None
                atomic_write_bytes(target, self.partial_path.read_bytes())  # other file system
                self.partial_path.unlink()
        self._release()
        fsync_dir(target.parent)
        return target

    def keep(self) -> Path:
        """Stop and move the partial file to `<name>-recovered[-N].log`: a new log
        replaces this unsaved one, which must not stay a `.partial` nobody hears of."""
        self.stop()
        return _keep_earlier_partial(self.partial_path, self.path)

    def discard(self) -> None:
        """Stop and delete the partial file (the user chose not to keep the log)."""
        self._writing = False
        self._pending.clear()
        if not self._file.closed:
            self.partial_path.unlink(missing_ok=True)
        self._release()

    def close(self) -> None:
        """Exit: stop; a partial file without rows is removed, one with rows is
        kept (and unlocked: the next LogOn of this name recovers it)."""
        try:
            self.stop()
        except LogFileError:
            pass
        if self.rows == 0:
            self.discard()
        self._release()

    def _release(self) -> None:
        if not self._file.closed:
            self._file.close()


def check_log_folder(folder: Path | str) -> None:
    """Refuse a folder where no log can be written (read-only, not a folder) now,
    at the start of a run, not at LogOn minutes into it."""
    folder = Path(folder)
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        raise LogFileError(str(folder), f"cannot write logs here: {exc.strerror or exc}") from None


def file_identity(path: Path | str) -> tuple[int, ...] | None:
    """What tells one file at `path` from another written there later (None: no
    file): device, inode, size, modification time."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)


def _partial_name(final: Path, n: int) -> Path:
    return final.with_name(f"{final.name}{'' if n == 1 else f'.{n}'}{PARTIAL_SUFFIX}")


def _claim_partial(final: Path) -> tuple[int, Path, tuple[Path, ...]]:
    """A new, empty, locked partial file for `final`: the first of `<name>.partial`,
    `<name>.2.partial`, ... that no live run holds.  Unlocked ones on the way that
    hold rows (a run that died before Save) are kept as `<name>-recovered.log`
    first; unlocked empty or header-only ones are reused."""
    kept: list[Path] = []
    n = 1
    while True:
        partial = _partial_name(final, n)
        try:
            fd = os.open(partial, os.O_RDWR | os.O_CREAT | _O_NOFOLLOW | _O_CLOEXEC, 0o644)
        except OSError as exc:
            raise LogFileError(str(final), f"cannot create a log here: {exc.strerror or exc}") from None
        try:
            if not _try_lock(fd):  # a live run's log in progress
                os.close(fd)
                n += 1
                continue
            if not _names(fd, partial):  # renamed or removed while we locked it: again
                os.close(fd)
                continue
            if _has_rows(fd):
                kept.append(_keep_earlier_partial(partial, final))
                os.close(fd)
                continue
            os.ftruncate(fd, 0)
            return fd, partial, tuple(kept)
        except BaseException:
            try:
                os.close(fd)
            except OSError:
                pass
            raise


_O_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_O_CLOEXEC = getattr(os, "O_CLOEXEC", 0)


def _try_lock(fd: int) -> bool:
    """An exclusive, non-blocking lock (flock: released when the process ends,
    however it ends); True where locks are not available."""
    if fcntl is None:
        return True
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError as exc:
        if exc.errno in (errno.EAGAIN, errno.EWOULDBLOCK, errno.EACCES):
            return False
        return True  # a file system without locks: unique names still apply
    return True


def _names(fd: int, path: Path) -> bool:
    """Whether `path` still names the open file `fd`."""
    try:
        st = os.stat(path, follow_symlinks=False)
    except FileNotFoundError:
        return False
    fst = os.fstat(fd)
    return (st.st_dev, st.st_ino) == (fst.st_dev, fst.st_ino)


def _has_rows(fd: int) -> bool:
    """Whether a (partial) log holds a data line, not just the header."""
    if os.fstat(fd).st_size > 4096:  # a header is a few hundred bytes
        return True
    head = os.pread(fd, 4096, 0).decode("latin-1")
    return any(ln.strip() and not ln.lstrip().startswith("%") for ln in head.split("\n"))


@contextlib.contextmanager
def _folder_lock(folder: Path) -> Iterator[None]:
    """Hold an exclusive lock on `folder` (a short one: a check and a rename)."""
    if fcntl is None:
        yield
        return
    try:
        fd = os.open(folder, os.O_RDONLY | _O_CLOEXEC)
    except OSError:
        yield
        return
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
        except OSError:
            pass
        yield
    finally:
        os.close(fd)


def _keep_earlier_partial(partial: Path, final: Path) -> Path:
    """A partial file with rows at LogOn is the unsaved log of a run that died:
    rather than truncate it, move it to `<name>-recovered[-N].log` (it loads as it
    is).  No existing file is replaced."""
    stem = final.name[: -len(SUFFIX)] if final.name.endswith(SUFFIX) else final.name
    n = 1
    while True:
        kept = final.with_name(f"{stem}-recovered{'' if n == 1 else f'-{n}'}{SUFFIX}")
        with _folder_lock(final.parent):
            if not os.path.lexists(kept):
                os.replace(partial, kept)
                return kept
        n += 1
