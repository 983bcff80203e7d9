"""Which ghost run a client showed on which session, so it comes back when the
client re-attaches.

The ghost belongs to what one client shows, not to the session: an operator and
an observer of the same session each have their own, and the session process
never reads the user's logs.  So it is remembered on the client's side, in the
user's own state folder ($XDG_STATE_HOME/quadtank, else ~/.local/state/quadtank),
keyed by the session's id *and* its start (ids are reused: `<user>-<n>` takes
the smallest free n, and a new session must not inherit an old one's ghost).
A file that cannot be read or written costs only the memory, never the TUI.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

from quadtank_tui.files.atomic import atomic_write_text

#: Sessions remembered at most (the oldest entry goes first).
KEEP = 20


@dataclass(frozen=True)
class RememberedGhost:
    """The ghost's file; its first row at process time `at` (None: at the
    current log's LogOn); `loaded_at`: the process time it was loaded at (where
    it is drawn until there is a LogOn)."""

    path: str
    at: float | None
    loaded_at: float


def state_file() -> Path:
    base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(base) / "quadtank" / "ghosts.json"


def read_entries(path: Path) -> dict[str, object]:
    """A client memory's entries by session (empty when unreadable: only the
    memory is lost).  The ghosts' file and the trends' (trend_memory.py) share it."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def write_entry(path: Path, session: str, entry: object | None) -> None:
    """Set `session`'s entry (None: forget it), newest last, the oldest past KEEP
    dropped; a file that cannot be written costs only the memory."""
    data = read_entries(path)
    data.pop(session, None)
    if entry is not None:
        data[session] = entry
    while len(data) > KEEP:
        data.pop(next(iter(data)))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(path, json.dumps(data, indent=1) + "\n", encoding="utf-8")
    except OSError:
        pass


def recall(session: str, path: Path | None = None) -> RememberedGhost | None:
    """The ghost remembered for `session` (its id and start), if any."""
    entry = read_entries(path or state_file()).get(session)
    if not isinstance(entry, dict):
        return None
    try:
        at = entry.get("at")
        return RememberedGhost(str(entry["path"]), None if at is None else float(at),
                               float(entry.get("loaded_at", 0.0)))
    except (KeyError, TypeError, ValueError):
        return None


def remember(session: str, ghost: RememberedGhost | None, path: Path | None = None) -> None:
    """Remember `ghost` for `session` (None: forget it)."""
    entry = None if ghost is None else {"path": ghost.path, "at": ghost.at, "loaded_at": ghost.loaded_at}
    write_entry(path or state_file(), session, entry)
