"""A process's state from /proc: alive, stopped, or gone (a zombie counts as gone),
its start time and its owner.

The session listing (session/runtime.py), the DAQ lock (session/lock.py) and the
guard (daq/guard.py) all ask it; where /proc cannot be read, a signal 0 tells alive
from gone.  A pid read from a file another user may have written can be 0 or
negative (never a probe of a process group), or beyond any pid the kernel
gives (PID_MAX): no process, never an OverflowError out of `os.kill`.
"""

from __future__ import annotations

import os

#: The largest pid Linux hands out (pid_max is at most 2**22): a larger number,
#: read from a file anyone may write, names no process.
PID_MAX = 1 << 22


def _pid_ok(pid: int) -> bool:
    return 0 < pid <= PID_MAX


def process_state(pid: int) -> str:
    """The state letter of /proc/PID/stat ("R", "S", "T" stopped, ...), "?" when it
    lives but /proc does not say, "" when it is gone or a zombie (or no pid: 0 or
    below, which a signal 0 would take for a process group; or above PID_MAX)."""
    if not _pid_ok(pid):
        return ""
    fields = _proc_stat(pid)
    if not fields:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return ""
        except PermissionError:
            return "?"
        return "?"
    state = fields[0].decode("ascii", "replace")
    return "" if state in ("Z", "X") else state


def pid_alive(pid: int, start: int | None = None) -> bool:
    """Whether `pid` runs (another user's process counts, a zombie does not) and,
    given its recorded start time, is still the same process and not a recycled pid."""
    if process_state(pid) == "":
        return False
    if start is not None:
        now = process_start(pid)
        return now is None or now == start
    return True


def _proc_stat(pid: int) -> list[bytes] | None:
    """The fields of /proc/<pid>/stat after the command name (state first), None
    where there is no such file."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            data = f.read()
        return data[data.rindex(b")") + 2:].split()
    except (OSError, ValueError):
        return None


def process_start(pid: int) -> int | None:
    """The start time of `pid` in clock ticks since boot (/proc), None where unknown."""
    if not _pid_ok(pid):
        return None
    fields = _proc_stat(pid)
    try:
        return None if fields is None else int(fields[19])
    except (ValueError, IndexError):
        return None


def process_owner(pid: int) -> int | None:
    """The real user id `pid` runs as (the `Uid:` line of /proc/PID/status: the
    kernel's, whoever wrote the pid down), None where unknown (no such process, or
    no /proc).  Not the owner of /proc/PID, which is the effective uid and, for a
    process that is not dumpable, root."""
    if not _pid_ok(pid):
        return None
    try:
        with open(f"/proc/{pid}/status", "rb") as f:
            for line in f:
                if line.startswith(b"Uid:"):
                    return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        return None
    return None
