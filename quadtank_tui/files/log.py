"""`.log` data files: the original's layout, written as a stream, read back by name.

The layout (thesis 5.3)::

    % TANK LOG-file
    % Created on: Jun 20 00:30:50 1997
    % Logged variables: y1 y2 u1 u2   TSamp: 1s

    0.622070  0.623535  0.300000  0.300000

:class:`LogWriter` is the Logging window's LogOn/LogOff/Save.  Rows go to a
partial file (`<name>.log.partial`) as they come, so a crash loses nothing that was
flushed, and that partial file is itself a valid log (the header is written and
synced first; each flush is whole lines, cut back if the write fails).  The
partial file is locked by its writer, so another run logging under the same name
takes `<name>.log.2.partial` instead of mixing rows into it.  Save renames it to
the final `.log` atomically.  Clock and `Created on:` stamp are injected for tests.

:func:`read_log` is the Python counterpart of the original's `load4t`: named
columns, tolerant of CRLF, trailing blanks, extra `%` lines and a missing
`Created on:`; a ragged or non-numeric row is refused naming file and line.
"""

from __future__ import annotations

import array
import contextlib
import errno
import io
import math
import os
import re
import tempfile
import time
from dataclasses import dataclass
from datetime import datetime
from decimal import Decimal
from pathlib import Path
from typing import Callable, Iterator, Mapping, Sequence

import numpy as np

try:  # POSIX; elsewhere the unique partial names alone keep runs apart
    import fcntl
except ImportError:  # pragma: no cover
    fcntl = None  # type: ignore[assignment]  # no module off POSIX: users test for None

from quadtank_tui.core.validation import ParameterError
from quadtank_tui.files.atomic import atomic_write_bytes, fsync_dir
from quadtank_tui.files.names import LOG_VARIABLES, check_variables
from quadtank_tui.files.regular import open_regular
from quadtank_tui.files.stamp import format_stamp, parse_stamp

HEADER = "% TANK LOG-file"
SUFFIX = ".log"
PARTIAL_SUFFIX = ".partial"
COLUMN_SEPARATOR = "  "

_VARIABLES_LINE = re.compile(r"%\s*Logged variables:(?P<rest>.*)")
_CREATED_LINE = re.compile(r"%\s*Created on:\s*(?P<stamp>.*?)\s*$")


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
        self._pending.append(format_row(row))
        self.rows += 1
        if len(self._pending) >= self._flush_rows or self.rows >= self.points:
            self.flush()
        if self.rows >= self.points:
            self.stop()
        return True

    def comment(self, text: str) -> bool:
        """A `%` line between the rows (an event: a fault switched on); readers skip it.
        False once logging has stopped."""
        if not self.running:
            return False
        line = " ".join(str(text).split())
        self._pending.append(f"% {line}\n")
        self.flush()
        return True

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
            self._pending.clear()
            self.rows = self._rows_written
            self.error = (f"cannot write ({exc.strerror or exc}): logging stopped; "
                          f"the {self.rows} whole rows written are kept")
            raise LogFileError(str(self.path), self.error) from None

    def _write(self, data: bytes) -> None:
        """Append `data` whole or not at all: a short write is undone."""
        view = memoryview(data)
        try:
            while view:
                view = view[self._file.write(view):]
        except OSError:
            try:
                os.ftruncate(self._file.fileno(), self._size)
            except OSError:
                pass
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


# --- reading ------------------------------------------------------------------------------

@dataclass(frozen=True)
class LogData:
    """A log's columns.  `data` has one row per sample, columns in `variables`
    order; `tsamp` is None when the header does not give it."""

    variables: tuple[str, ...]
    tsamp: float | None
    data: np.ndarray
    created: datetime | None = None
    created_text: str | None = None
    warnings: tuple[str, ...] = ()

    def __getitem__(self, name: str) -> np.ndarray:
        """One column by name, e.g. ``log["y1"]``."""
        try:
            return self.data[:, self.variables.index(name)]
        except ValueError:
            raise KeyError(f"no column {name!r} (logged: {' '.join(self.variables)})") from None

    @property
    def rows(self) -> int:
        return int(self.data.shape[0])

    @property
    def duration(self) -> float | None:
        """Seconds covered: rows x TSamp (None without TSamp)."""
        return None if self.tsamp is None else self.rows * self.tsamp

    def columns(self) -> dict[str, np.ndarray]:
        """Every column by name (what `load4t` put in the workspace)."""
        return {name: self[name] for name in self.variables}


#: The longest line of a log, in characters: a row of every loggable variable as
#: `%f` is under 100; a longer line is not a TANK log (one line of 10 million
#: columns took 1.3 GB to refuse when the whole file was split first).
MAX_LINE = 4096
#: The most rows read: 8 h of 10 ms samples is 2.9 million (72 bytes a row in memory).
MAX_ROWS = 5_000_000
#: The most variables a header may declare (a log has at most nine).
MAX_COLUMNS = 64
#: Comment and blank lines allowed beside the rows (a `% late:` note per late row).
MAX_OTHER_LINES = MAX_ROWS + 10_000


def read_log(path: Path | str, *, max_rows: int = MAX_ROWS, max_line: int = MAX_LINE) -> LogData:
    """Read a `.log` (or a `.log.partial` left by a killed run) as a stream: one
    line at a time, at most `max_line` characters each and `max_rows` rows, the
    values straight into one float64 buffer, so memory stays near 8 bytes a value
    whatever the file holds."""
    path = Path(path)
    try:
        f = open_regular(path)
    except FileNotFoundError:
        raise LogFileError(str(path), "no such file") from None
    except OSError as exc:
        raise LogFileError(str(path), f"cannot read: {exc.strerror or exc}") from None
    with io.TextIOWrapper(f, encoding="latin-1", newline="\n") as text:
        try:
            return _parse_lines(text.readline, str(path), max_rows, max_line)
        except OSError as exc:
            raise LogFileError(str(path), f"cannot read: {exc.strerror or exc}") from None


def parse_log(data: bytes | str, *, name: str = "<log>", max_rows: int = MAX_ROWS,
              max_line: int = MAX_LINE) -> LogData:
    """Parse `.log` content (see :func:`read_log`)."""
    text = data.decode("latin-1") if isinstance(data, bytes) else data
    return _parse_lines(io.StringIO(text, newline="\n").readline, name, max_rows, max_line)


def _parse_lines(readline: Callable[[int], str], name: str, max_rows: int, max_line: int) -> LogData:
    """The log whose lines `readline(limit)` gives, one at a time."""
    variables: tuple[str, ...] | None = None
    tsamp: float | None = None
    created: datetime | None = None
    created_text: str | None = None
    warnings: list[str] = []
    values_read = array.array("d")
    rows = other = 0
    # A last line without its line end may have been cut mid-number ("0.300" of
    # "0.300000"): it is kept only if its last value is as long as the row
    # before's (or `%f`'s six decimals), else dropped with a warning.
    last_decimals = 6
    no = 0
    while True:
        raw = readline(max_line + 1)
        if not raw:
            break
        no += 1
        torn = not raw.endswith("\n")
        if torn and len(raw) > max_line:
            raise LogFileError(name, f"a line longer than {max_line} characters: not a TANK log "
                               "(a row is a few numbers)", no)
        line = raw.rstrip("\n").rstrip("\r").strip()
        if line.startswith("%"):
            if no == 1 and line.upper().startswith("% TANK PAR"):
                raise LogFileError(name, "this is a .par parameter file, not a .log", no)
            if variables is None and (m := _VARIABLES_LINE.fullmatch(line)):
                variables, tsamp = _parse_variables(m, name, no, warnings)
            elif created_text is None and (m := _CREATED_LINE.fullmatch(line)):
                created_text = m.group("stamp")
                created = parse_stamp(created_text)
            other = _count_other(other, name, no)
            continue
        line = line.split("%", 1)[0].strip()  # a trailing comment, as MATLAB allows
        if not line:
            other = _count_other(other, name, no)
            continue
        if variables is None:
            raise LogFileError(name, "data before the '% Logged variables:' header line", no)
        cells = line.split()
        try:
            values = [float(c) for c in cells]
            ok = len(values) == len(variables) and all(math.isfinite(v) for v in values)
        except ValueError:
            values, ok = [], False
        if ok and not (torn and _decimals(cells[-1]) != last_decimals):
            if rows >= max_rows:
                raise LogFileError(name, f"more than {max_rows} rows: too long a log to read "
                                   f"(8 h of 10 ms samples is 2.9 million)", no)
            values_read.extend(values)
            rows += 1
            last_decimals = _decimals(cells[-1])
        elif torn:
            warnings.append(f"{name}, line {no}: incomplete last row dropped (file cut off while writing)")
        elif len(cells) != len(variables):
            raise LogFileError(name, f"{len(cells)} values where the header declares {len(variables)} "
                               f"({' '.join(variables)})", no)
        else:
            raise LogFileError(name, f"not a number in {line[:60]!r}", no)
    if variables is None:
        raise LogFileError(name, "no '% Logged variables:' header line: not a TANK log file", 1)
    if not created_text:
        warnings.append(f"{name}: no 'Created on:' line")
    data = np.frombuffer(values_read, dtype=float).reshape(rows, len(variables)) if rows else \
        np.zeros((0, len(variables)))
    return LogData(variables, tsamp, data, created, created_text, tuple(warnings))


def _count_other(seen: int, name: str, no: int) -> int:
    """One more comment or blank line; LogFileError past MAX_OTHER_LINES (a file of
    nothing but blank lines is read in bounded time too)."""
    if seen >= MAX_OTHER_LINES:
        raise LogFileError(name, f"more than {MAX_OTHER_LINES} comment or blank lines: not a TANK log", no)
    return seen + 1


def _decimals(cell: str) -> int:
    """Digits after the decimal point of a number as written (-1: no point)."""
    mantissa = cell.lower().split("e", 1)[0]
    return len(mantissa) - mantissa.index(".") - 1 if "." in mantissa else -1


def _parse_variables(m: re.Match[str], name: str, no: int, warnings: list[str]) -> tuple[tuple[str, ...], float | None]:
    """`y1 y2 u1 u2   TSamp: 1s` -> the names and the sampling time in seconds."""
    names_text, has_tsamp, tsamp_text = m.group("rest").partition("TSamp:")
    names = tuple(names_text.split())
    if not names:
        raise LogFileError(name, "no variable names on the 'Logged variables:' line", no)
    if len(names) > MAX_COLUMNS:
        raise LogFileError(name, f"{len(names)} variables on the 'Logged variables:' line: a log has "
                           f"at most {MAX_COLUMNS}", no)
    if len(set(names)) != len(names):
        raise LogFileError(name, f"a variable is named twice: {' '.join(names)}", no)
    unknown = [n for n in names if n not in LOG_VARIABLES]
    if unknown:
        warnings.append(f"{name}, line {no}: unusual variable names {' '.join(unknown)} (kept)")
    text = tsamp_text.strip().removesuffix("s").strip()
    if not has_tsamp:
        warnings.append(f"{name}, line {no}: no TSamp on the 'Logged variables:' line")
        return names, None
    try:
        tsamp = float(text)
    except ValueError:
        tsamp = math.nan
    if not (math.isfinite(tsamp) and tsamp > 0):
        raise LogFileError(name, f"TSamp is not a positive number of seconds: {text!r}", no)
    return names, tsamp
