"""Where sessions live on the machine: one socket and one small JSON record each.

The runtime folder (the lab configuration's, else $QUADTANK_RUNTIME, else
/tmp/quadtank-sessions) is shared by every user, sticky like /tmp: anyone may put
a session there, nobody may remove another's.  A session's socket is its owner's
alone (mode 0600); its record, readable by all, is what `quadtank sessions` lists.
A record whose process is gone (a session killed with SIGKILL) is stale: listing
the sessions removes it and its socket.
"""

from __future__ import annotations

import dataclasses
import json
import os
import tempfile
from pathlib import Path

from quadtank_tui.files.proc import process_state
from quadtank_tui.session.info import SessionInfo

class NoSession(LookupError):
    """No session matches what was asked; the message says what there is."""


def runtime_dir(configured: Path | None = None) -> Path:
    """The runtime folder (`configured`, else the lab configuration's), created
    sticky and world-writable (1777) if missing."""
    from quadtank_tui.session.lab import ensure_shared_dir, load_lab_config

    return ensure_shared_dir(configured or load_lab_config().runtime_dir)


def pid_alive(pid: int) -> bool:
    """A running process (a zombie counts as gone)."""
    return process_state(pid) != ""


def record_path(runtime: Path, session_id: str) -> Path:
    return runtime / f"{session_id}.json"


def socket_path(runtime: Path, session_id: str) -> Path:
    return runtime / f"{session_id}.sock"


def claim_id(runtime: Path, user: str) -> str:
    """A new session id, `<user>-<n>` with the smallest free n, claimed by creating its
    record (O_EXCL: two sessions starting at once get different ids)."""
    list_sessions(runtime)  # prunes stale records, so their ids come free
    n = 1
    while True:
        sid = f"{user}-{n}"
        try:
            fd = os.open(record_path(runtime, sid), os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            n += 1
            continue
        os.close(fd)
        return sid


def write_record(runtime: Path, info: SessionInfo) -> None:
    """Replace the session's record atomically (a reader never sees half of it)."""
    fd, tmp = tempfile.mkstemp(prefix=f".{info.id}.", suffix=".tmp", dir=runtime)
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(dataclasses.asdict(info), f)
        os.chmod(tmp, 0o644)
        os.replace(tmp, record_path(runtime, info.id))
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def read_record(path: Path) -> SessionInfo | None:
    """The record at `path`; None if it is not one (being claimed, or garbage)."""
    try:
        obj = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(obj, dict):
        return None
    names = {f.name for f in dataclasses.fields(SessionInfo)}
    try:
        return SessionInfo(**{k: v for k, v in obj.items() if k in names})
    except TypeError:
        return None


def remove_files(runtime: Path, session_id: str) -> None:
    """The session's socket and record (what a stop leaves behind: nothing)."""
    for path in (socket_path(runtime, session_id), record_path(runtime, session_id)):
        try:
            path.unlink()
        except FileNotFoundError:
            pass
        except PermissionError:
            pass  # another user's stale files in a sticky folder: theirs to remove


def list_sessions(runtime: Path, *, prune: bool = True) -> list[SessionInfo]:
    """The live sessions, oldest first; stale records (process gone) are removed."""
    out = []
    for path in sorted(runtime.glob("*.json")):
        info = read_record(path)
        if info is None:
            continue
        if not pid_alive(info.pid):
            if prune:
                remove_files(runtime, info.id)
            continue
        out.append(info)
    out.sort(key=lambda i: (i.started, i.id))
    return out


def find_session(runtime: Path, wanted: str | None, uid: int, *, interactive: bool = False) -> SessionInfo:
    """The session named `wanted`, or (None) the caller's only one (`interactive`:
    not counting headless runs); NoSession says what there is otherwise."""
    sessions = list_sessions(runtime)
    if wanted is not None:
        for info in sessions:
            if info.id == wanted:
                return info
        known = ", ".join(i.id for i in sessions) or "none"
        raise NoSession(f"no session {wanted!r} (sessions: {known})")
    mine = [i for i in sessions if i.uid == uid and not (interactive and i.headless)]
    if not mine:
        raise NoSession("you have no running session")
    if len(mine) > 1:
        raise NoSession(f"you have {len(mine)} sessions ({', '.join(i.id for i in mine)}): name one")
    return mine[0]
