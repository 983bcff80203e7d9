"""A Unix socket's address however deep its folder: the kernel takes at most 107
bytes of path (sun_path), and a session's socket lies in its owner's folder of the
runtime folder (`.../users/UID/ID.sock`, a private session's one level deeper),
which under a long $QUADTANK_RUNTIME or $TMPDIR is more.  A longer path is reached
through the folder opened first (O_PATH): `/proc/self/fd/N/NAME` names the same
file, bound or connected to as the long path would be."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Iterator

#: Paths up to this many bytes are used as they are.
SUN_PATH = 107


@contextlib.contextmanager
def unix_address(path: str | Path) -> Iterator[str]:
    """An address for bind or connect that names `path` (itself when short enough)."""
    text = str(path)
    if len(os.fsencode(text)) <= SUN_PATH:
        yield text
        return
    folder, name = os.path.split(text)
    fd = os.open(folder or ".", os.O_PATH | os.O_DIRECTORY | os.O_CLOEXEC)
    try:
        yield f"/proc/self/fd/{fd}/{name}"
    finally:
        os.close(fd)
