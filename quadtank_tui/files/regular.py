"""Reading a file the user named, refusing anything that is not a regular file
before reading from it: a FIFO would block `open()` forever, a directory or a
device is never a parameter file, script or log.

The file is opened with O_NONBLOCK (so opening a FIFO returns at once), then
`fstat` decides; for a regular file the flag changes nothing."""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path
from typing import BinaryIO

_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


class NotRegularFile(OSError):
    """The path names something other than a regular file."""


def open_regular(path: Path | str) -> BinaryIO:
    """The file opened for reading in binary, to be read as a stream (a big log);
    FileNotFoundError, NotRegularFile or another OSError."""
    fd = _open_regular(path)
    try:
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def _open_regular(path: Path | str) -> int:
    """A descriptor of `path` once fstat says it is a regular file."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0)
    fd = os.open(path, flags)
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            kind = next((what for test, what in _KINDS if test(mode)), "not a regular file")
            raise NotRegularFile(errno.EINVAL, f"{kind}, not a file", str(path))
    except BaseException:
        os.close(fd)
        raise
    return fd


def read_regular(path: Path | str, limit: int | None = None) -> bytes:
    """The file's bytes (at most `limit` + 1 of them, so a caller can tell a file
    larger than `limit`).  FileNotFoundError, NotRegularFile or another OSError."""
    fd = _open_regular(path)
    try:
        chunks: list[bytes] = []
        size = 0
        while limit is None or size <= limit:
            chunk = os.read(fd, 1 << 16 if limit is None else min(1 << 16, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        return b"".join(chunks)
    finally:
        os.close(fd)
