"""Reading a file another user may have written, and showing what it says.

In the lab's shared runtime folder (session records, lock records) anyone may have
put anything under a name we look for: a FIFO (an `open` that never returns), a
link to /dev/zero (a read that never ends), a 3 GB sparse file, a link to a file
of root's.  So such a file is opened without following a link and without
blocking (O_NOFOLLOW, O_NONBLOCK), `fstat` must say it is a regular file (of the
owner expected, when one is), and at most `limit` bytes are read: whatever lies
there costs one open, one fstat and one bounded read.

Text read from such a file is shown through `shown`: a control character (an
escape sequence retitles or clears the reader's terminal) is written as its
escape, never sent raw.
"""

from __future__ import annotations

import os
import stat
import unicodedata
from pathlib import Path


class Untrusted(OSError):
    """The file is not one to read: not a regular file, not its owner's, too large."""


def read_untrusted(path: Path | str, limit: int, *, owner: int | None = None,
                   dir_fd: int | None = None) -> tuple[bytes, os.stat_result]:
    """The bytes of the regular file `path` (and its fstat), refused (Untrusted) if
    it is a link, not a regular file, not owned by `owner` (when given), or larger
    than `limit` bytes; FileNotFoundError or another OSError if it cannot be opened.
    `dir_fd`: `path` is a name inside that open folder (no link on the way)."""
    flags = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_NOCTTY | os.O_CLOEXEC
    fd = os.open(path, flags, dir_fd=dir_fd)
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise Untrusted(f"{path}: not a regular file")
        if owner is not None and st.st_uid != owner:
            raise Untrusted(f"{path}: owned by uid {st.st_uid}, not {owner}")
        if st.st_size > limit:
            raise Untrusted(f"{path}: {st.st_size} bytes, more than {limit}")
        chunks: list[bytes] = []
        size = 0
        while size <= limit:  # the size may grow after fstat: read at most limit + 1
            chunk = os.read(fd, limit + 1 - size)
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if size > limit:
            raise Untrusted(f"{path}: more than {limit} bytes")
        return b"".join(chunks), st
    finally:
        os.close(fd)


def shown(text: object) -> str:
    """`text` as it may be printed on a terminal: every control or format character
    (C0, DEL, C1, and Unicode's other non-printing ones, such as bidirectional
    overrides) written as a Python escape (`\\x1b`, `\\u202e`), a backslash doubled."""
    s = str(text)
    if s.isprintable() and "\\" not in s:
        return s
    out = []
    for ch in s:
        if ch == "\\":
            out.append("\\\\")
        elif ch.isprintable() and unicodedata.category(ch) not in ("Cc", "Cf", "Zl", "Zp"):
            out.append(ch)
        else:
            code = ord(ch)
            out.append(f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}")
    return "".join(out)
