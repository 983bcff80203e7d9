"""How a client's trends were set on a session (time window, autoscale, units,
time axis), so they come back when the client re-attaches (issue 43: they
reset to 5 min, autoscaled, normalized on every attach).

Like the ghost (ghost_memory.py) this is what one client shows, not the
session's: kept in the user's own state folder, keyed by the session's id and
start (a new session that reuses an id starts from the defaults).  A file that
cannot be read or written costs only the memory, never the TUI.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from pathlib import Path

from quadtank_tui.files.ghost_memory import read_entries, write_entry
from quadtank_tui.files.ghost_memory import state_file as ghost_file


@dataclass(frozen=True)
class TrendSettings:
    """window_index: the `z` window (an index into the trends' WINDOWS); autoscale
    (`Z`); physical: the plant's units (`u`); clock_axis: clock time on x (`c`)."""

    window_index: int = 1
    autoscale: bool = True
    physical: bool = False
    clock_axis: bool = False


def state_file() -> Path:
    return ghost_file().with_name("trends.json")


def recall(session: str, path: Path | None = None) -> TrendSettings | None:
    """The settings remembered for `session` (its id and start), if any and sound."""
    entry = read_entries(path or state_file()).get(session)
    if not isinstance(entry, dict):
        return None
    kinds = {f.name: type(getattr(TrendSettings(), f.name)) for f in fields(TrendSettings)}
    if set(entry) != set(kinds) or any(type(entry[k]) is not kind for k, kind in kinds.items()):
        return None  # another version's file, or a hand-edited one
    return TrendSettings(**entry)


def remember(session: str, settings: TrendSettings, path: Path | None = None) -> None:
    """Remember `settings` for `session` (the defaults: forget it)."""
    write_entry(path or state_file(), session, None if settings == TrendSettings() else asdict(settings))
