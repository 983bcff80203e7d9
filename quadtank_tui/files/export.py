"""Exports of a log for tools that do not read the original's layout.

`.mat` (MATLAB 5, via scipy.io.savemat): one column vector per logged variable,
named as in the header, plus the scalar `TSamp` (seconds) when the log has it -
the workspace the original's `load4t` left.  `.csv`: a header row of the names,
then one row per sample, values as the shortest decimal that reads back exactly.
Both are written atomically, never over an existing file unless asked to, and
never as a reserved parameter file (`default.par`).
"""

from __future__ import annotations

import io
from pathlib import Path

from quadtank_tui.files.atomic import atomic_write_bytes
from quadtank_tui.files.log_reader import LogData
from quadtank_tui.files.par import RESERVED
from quadtank_tui.files.par import SUFFIX as PAR_SUFFIX

FORMATS = ("mat", "csv")


def mat_bytes(log: LogData) -> bytes:
    """The `.mat` file's content."""
    import scipy.io  # here, not at module level: it costs every `quadtank` start ~0.2 s

    out: dict[str, object] = {name: log[name].reshape(-1, 1) for name in log.variables}
    if log.tsamp is not None:
        out["TSamp"] = log.tsamp
    buffer = io.BytesIO()
    scipy.io.savemat(buffer, out, format="5", oned_as="column")
    return buffer.getvalue()


def csv_text(log: LogData) -> str:
    """The `.csv` file's content (LF line ends)."""
    lines = [",".join(log.variables)]
    lines += [",".join(repr(float(x)) for x in row) for row in log.data]
    return "\n".join(lines) + "\n"


def export_log(log: LogData, path: Path | str, fmt: str, *, overwrite: bool = False) -> Path:
    """Write `log` to `path` as `fmt` ("mat" or "csv"); returns the path.  The
    reserved parameter-file names (`default.par`, `preset.par`) are refused, an
    existing file is kept (FileExistsError) unless `overwrite`."""
    path = Path(path)
    if path.suffix.lower() == PAR_SUFFIX and path.stem.lower() in RESERVED:
        raise ValueError(f"{path}: {RESERVED[path.stem.lower()]}; an export never takes that name")
    if fmt == "mat":
        return atomic_write_bytes(path, mat_bytes(log), overwrite=overwrite)
    if fmt == "csv":
        return atomic_write_bytes(path, csv_text(log).encode("ascii"), overwrite=overwrite)
    raise ValueError(f"export format must be one of {', '.join(FORMATS)}, got {fmt!r}")
