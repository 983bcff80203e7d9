"""A process's state from /proc: alive, stopped, or gone (a zombie counts as gone).

The session listing (session/runtime.py) and the guard (daq/guard.py) both ask it;
where /proc cannot be read, a signal 0 tells alive from gone.
"""

from __future__ import annotations

import os
from pathlib import Path


def process_state(pid: int) -> str:
    """The state letter of /proc/PID/stat ("R", "S", "T" stopped, ...), "?" when it
    lives but /proc does not say, "" when it is gone or a zombie."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return ""
        except PermissionError:
            return "?"
        return "?"
    return "" if state in ("Z", "X") else state
