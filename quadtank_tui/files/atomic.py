"""Atomic file replacement: a reader (or a crash) sees the old file or the new one,
never half of either.

The new file gets the mode a plain `open()` would give it (0666 less the umask),
or the mode of the file it replaces: mkstemp's private 0600 would hide a saved
`.par` from the other lab users.

The data goes to a temporary file in the target's own folder (a rename is only
atomic within one file system), is fsynced, then `os.replace`d over the target; the
folder is fsynced too so the rename itself survives a power cut.  If anything fails
before the rename, the temporary file is removed and the old file is untouched.
"""

from __future__ import annotations

import errno
import os
import stat
import tempfile
import threading
from pathlib import Path

_UMASK_LOCK = threading.Lock()


def current_umask() -> int:
    """The process's umask (read from /proc where there is one: setting it to
    read it back is a moment when another thread's files get the wrong mode)."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    with _UMASK_LOCK:
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def _mode_for(path: Path) -> int:
    """The replaced file's permission bits, else what open() would create."""
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        return 0o666 & ~current_umask()


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


def atomic_write_bytes(path: Path | str, data: bytes, *, overwrite: bool = True) -> Path:
    """Replace `path` by `data` atomically; returns the path written.  With
    `overwrite` False an existing `path` is left as it is (FileExistsError), also
    one that appears while writing.  An error names `path`, never the temporary
    file (which is gone by then)."""
    path = Path(path)
    mode = _mode_for(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise _naming(exc, path) from None
    try:
        os.fchmod(fd, mode)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        if overwrite:
            os.replace(tmp, path)
        else:
            _link_new(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(exc, OSError):
            raise _naming(exc, path) from None
        raise
    fsync_dir(path.parent)
    return path


def _link_new(tmp: str, path: Path) -> None:
    """Give `tmp`'s file the name `path` unless `path` exists (a hard link fails
    then, atomically); where links are not supported, check first."""
    try:
        os.link(tmp, path)
    except FileExistsError:
        raise
    except OSError:
        if os.path.lexists(path):
            raise FileExistsError(errno.EEXIST, "File exists", str(path)) from None
        os.replace(tmp, path)
        return
    os.unlink(tmp)


def _naming(exc: OSError, path: Path) -> OSError:
    """The same error about `path` (the user's file), not the temporary one."""
    if exc.errno is None:
        return exc
    return type(exc)(exc.errno, exc.strerror or str(exc), str(path))


def atomic_write_text(path: Path | str, text: str, encoding: str = "ascii") -> Path:
    """`atomic_write_bytes` for text; `\\n` line ends are written as they are."""
    return atomic_write_bytes(path, text.encode(encoding))
