"""Atomic file replacement: a reader (or a crash) sees the old file or the new one,
never half of either.

The data goes to a temporary file in the target's own folder (a rename is only
atomic within one file system), is fsynced, then `os.replace`d over the target; the
folder is fsynced too so the rename itself survives a power cut.  If anything fails
before the rename, the temporary file is removed and the old file is untouched.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def fsync_dir(folder: Path) -> None:
    """Make a rename in `folder` durable (a no-op where folders cannot be opened)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def atomic_write_bytes(path: Path | str, data: bytes) -> Path:
    """Replace `path` by `data` atomically; returns the path written."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    fsync_dir(path.parent)
    return path


def atomic_write_text(path: Path | str, text: str, encoding: str = "ascii") -> Path:
    """`atomic_write_bytes` for text; `\\n` line ends are written as they are."""
    return atomic_write_bytes(path, text.encode(encoding))
