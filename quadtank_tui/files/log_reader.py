"""Reading `.log` data files back by name (the writer, and the layout, are in log_writer.py).

:func:`read_log` is the Python counterpart of the original's `load4t`: named
columns, tolerant of CRLF, trailing blanks, extra `%` lines and a missing
`Created on:`; a ragged or non-numeric row is refused naming file and line.
"""

from __future__ import annotations

import array
import io
import math
import os
import re
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Callable

import numpy as np

# LogFileError is the writer's and the reader's: a reader imports it from here.
from quadtank_tui.files.log_writer import LogFileError as LogFileError
from quadtank_tui.files.names import LOG_VARIABLES
from quadtank_tui.files.regular import open_regular
from quadtank_tui.files.stamp import parse_stamp

_VARIABLES_LINE = re.compile(r"%\s*Logged variables:(?P<rest>.*)")
_CREATED_LINE = re.compile(r"%\s*Created on:\s*(?P<stamp>.*?)\s*$")


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
#: Bytes of a row of nine columns in a log this program writes, about (for messages).
ROW_BYTES = 93
#: The most variables a header may declare (a log has at most nine).
MAX_COLUMNS = 64
#: Comment and blank lines allowed beside the rows (a `% late:` note per late row).
MAX_OTHER_LINES = MAX_ROWS + 10_000


def read_log(path: Path | str, *, max_rows: int = MAX_ROWS, max_line: int = MAX_LINE,
             max_bytes: tuple[int, str] | None = None) -> LogData:
    """Read a `.log` (or a `.log.partial` left by a killed run) as a stream: one
    line at a time, at most `max_line` characters each and `max_rows` rows, the
    values straight into one float64 buffer, so memory stays near 8 bytes a value
    whatever the file holds.  `max_bytes` (bytes, who reads): a file larger than
    that is refused from its size, before a line is read."""
    path = Path(path)
    try:
        f = open_regular(path)
    except FileNotFoundError:
        raise LogFileError(str(path), "no such file") from None
    except OSError as exc:
        raise LogFileError(str(path), f"cannot read: {exc.strerror or exc}") from None
    if max_bytes is not None:
        size = os.fstat(f.fileno()).st_size
        if size > max_bytes[0]:
            f.close()
            raise LogFileError(str(path), f"{size / 1e6:,.1f} MB, larger than {max_bytes[1]} reads "
                               f"({max_bytes[0] / 1e6:g} MB, about {max_bytes[0] // ROW_BYTES:,} rows of 9 columns)")
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
