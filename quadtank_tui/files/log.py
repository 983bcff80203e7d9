"""`.log` data files: the original's layout, written as a stream, read back by name.

The layout (thesis 5.3)::

    % TANK LOG-file
    % Created on: Jun 20 00:30:50 1997
    % Logged variables: y1 y2 u1 u2   TSamp: 1s

    0.622070  0.623535  0.300000  0.300000

:class:`LogWriter` is the Logging window's LogOn/LogOff/Save.  Rows go to a
partial file (`<name>.log.partial`) as they come, so a crash loses nothing that was
flushed, and that partial file is itself a valid log (the header is written and
synced first; each flush is one `write` of whole lines).  Save renames it to the
final `.log` atomically.  Clock and `Created on:` stamp are injected for tests.

:func:`read_log` is the Python counterpart of the original's `load4t`: named
columns, tolerant of CRLF, trailing blanks, extra `%` lines and a missing
`Created on:`; a ragged or non-numeric row is refused naming file and line.
"""

from __future__ import annotations

import errno
import math
import os
import re
import time
from dataclasses import dataclass
from datetime import datetime
from decimal import Decimal
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from quadtank_tui.core.parameters import LOG_VARIABLES, POINTS_MAX, check_variables
from quadtank_tui.core.validation import ParameterError
from quadtank_tui.files.atomic import atomic_write_bytes, fsync_dir
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

    Creating the writer is LogOn: it writes the header to `<path>.partial`.  Then
    :meth:`append` once per sample (the values by variable name; extra names are
    ignored).  Logging stops by itself after `points` rows, or at :meth:`stop`
    (LogOff).  :meth:`save` renames the partial file to the final `.log`;
    :meth:`discard` removes it.  A partial file already there at LogOn (a run
    that died before Save) is kept as `<name>-recovered.log`, see `recovered`.

    Rows are handed to the OS every `flush_rows` rows (default: every row, a
    few dozen bytes per sample) and fsynced at most every `fsync_interval` s of
    `clock` time, so a killed process loses nothing and a power cut at most about
    a second.
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
        if isinstance(points, bool) or not isinstance(points, int) or not 1 <= points <= POINTS_MAX:
            raise LogFileError(str(path), f"points must be a whole number 1..{POINTS_MAX}, got {points!r}")
        if flush_rows < 1:
            raise LogFileError(str(path), f"flush_rows must be >= 1, got {flush_rows}")
        header = format_header(self.variables, tsamp, created or datetime.now())
        self.path = Path(path)
        self.partial_path = self.path.with_name(self.path.name + PARTIAL_SUFFIX)
        self.tsamp = float(tsamp)
        self.points = points
        self.rows = 0
        self._flush_rows = flush_rows
        self._fsync_interval = fsync_interval
        self._clock = clock
        self._pending: list[str] = []
        #: Where an earlier run's unsaved partial file was moved, if there was one.
        self.recovered = _keep_earlier_partial(self.partial_path, self.path)
        self._file = open(self.partial_path, "wb", buffering=0)
        self._file.write(header.encode("ascii"))
        os.fsync(self._file.fileno())
        self._last_sync = clock()

    @property
    def running(self) -> bool:
        """True between LogOn and LogOff (or the last point)."""
        return self._file is not None and not self._file.closed

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
            raise LogFileError(str(self.partial_path), f"sample has no value for {exc.args[0]!r}") from None
        bad = [n for n, v in zip(self.variables, row) if not math.isfinite(v)]
        if bad:
            raise LogFileError(str(self.partial_path), f"not a finite number: {', '.join(bad)}")
        self._pending.append(format_row(row))
        self.rows += 1
        if len(self._pending) >= self._flush_rows or self.rows >= self.points:
            self.flush()
        if self.rows >= self.points:
            self.stop()
        return True

    def flush(self) -> None:
        """Hand the pending rows to the OS in one write; fsync if a second passed."""
        if self._file is None or self._file.closed:
            return
        if self._pending:
            data = "".join(self._pending).encode("ascii")
            self._pending.clear()
            view = memoryview(data)
            while view:
                view = view[self._file.write(view):]
        now = self._clock()
        if now - self._last_sync >= self._fsync_interval:
            os.fsync(self._file.fileno())
            self._last_sync = now

    def stop(self) -> None:
        """LogOff: write and sync what is pending and close the partial file."""
        if not self.running:
            return
        assert self._file is not None
        self._last_sync = -math.inf
        self.flush()
        self._file.close()

    def save(self, path: Path | str | None = None) -> Path:
        """Stop if running, then move the partial file to `path` (default: the
        path given at LogOn) atomically; returns the final path."""
        self.stop()
        target = Path(path) if path is not None else self.path
        try:
            os.replace(self.partial_path, target)
        except OSError as exc:
            if exc.errno != errno.EXDEV:
                raise
            atomic_write_bytes(target, self.partial_path.read_bytes())  # other file system
            self.partial_path.unlink()
        fsync_dir(target.parent)
        return target

    def keep(self) -> Path | None:
        """Stop and move the partial file to `<name>-recovered[-N].log`: a new log
        replaces this unsaved one, which must not stay a `.partial` nobody hears of."""
        self.stop()
        return _keep_earlier_partial(self.partial_path, self.path)

    def discard(self) -> None:
        """Stop and delete the partial file (the user chose not to keep the log)."""
        self.stop()
        self.partial_path.unlink(missing_ok=True)


def _keep_earlier_partial(partial: Path, final: Path) -> Path | None:
    """A partial file at LogOn is the unsaved log of a run that died: rather than
    truncate it, move it to `<name>-recovered[-N].log` (it loads as it is)."""
    if not partial.exists():
        return None
    stem = final.name[: -len(SUFFIX)] if final.name.endswith(SUFFIX) else final.name
    n = 1
    while True:
        kept = final.with_name(f"{stem}-recovered{'' if n == 1 else f'-{n}'}{SUFFIX}")
        if not kept.exists():
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


def read_log(path: Path | str) -> LogData:
    """Read a `.log` (or a `.log.partial` left by a killed run)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise LogFileError(str(path), "no such file") from None
    except OSError as exc:
        raise LogFileError(str(path), f"cannot read: {exc.strerror or exc}") from None
    return parse_log(data, name=str(path))


def parse_log(data: bytes | str, *, name: str = "<log>") -> LogData:
    """Parse `.log` content (see :func:`read_log`)."""
    text = data.decode("latin-1") if isinstance(data, bytes) else data
    lines = text.split("\n")
    unterminated_last = not text.endswith("\n")
    variables: tuple[str, ...] | None = None
    tsamp: float | None = None
    created: datetime | None = None
    created_text: str | None = None
    warnings: list[str] = []
    rows: list[list[float]] = []
    for no, raw in enumerate(lines, start=1):
        line = raw.rstrip("\r").strip()
        if line.startswith("%"):
            if no == 1 and line.upper().startswith("% TANK PAR"):
                raise LogFileError(name, "this is a .par parameter file, not a .log", no)
            if variables is None and (m := _VARIABLES_LINE.fullmatch(line)):
                variables, tsamp = _parse_variables(m, name, no, warnings)
            elif created_text is None and (m := _CREATED_LINE.fullmatch(line)):
                created_text = m.group("stamp")
                created = parse_stamp(created_text)
            continue
        line = line.split("%", 1)[0].strip()  # a trailing comment, as MATLAB allows
        if not line:
            continue
        if variables is None:
            raise LogFileError(name, "data before the '% Logged variables:' header line", no)
        cells = line.split()
        try:
            values = [float(c) for c in cells]
            ok = len(values) == len(variables) and all(math.isfinite(v) for v in values)
        except ValueError:
            values, ok = [], False
        if ok:
            rows.append(values)
        elif unterminated_last and no == len(lines):
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
    array = np.array(rows, dtype=float).reshape(len(rows), len(variables))
    return LogData(variables, tsamp, array, created, created_text, tuple(warnings))


def _parse_variables(m: re.Match[str], name: str, no: int, warnings: list[str]) -> tuple[tuple[str, ...], float | None]:
    """`y1 y2 u1 u2   TSamp: 1s` -> the names and the sampling time in seconds."""
    names_text, has_tsamp, tsamp_text = m.group("rest").partition("TSamp:")
    names = tuple(names_text.split())
    if not names:
        raise LogFileError(name, "no variable names on the 'Logged variables:' line", no)
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
