"""Where sessions live on the machine: one socket and one small JSON record each.

The runtime folder (the lab configuration's, else $QUADTANK_RUNTIME, else
/tmp/quadtank-sessions) is shared by every user, sticky like /tmp: anyone may put
a session there, nobody may remove another's.  A session's socket is its owner's
alone (mode 0600); its record, readable by all, is what `quadtank sessions` lists.

A session that ends says why in its record (`ended`, `ended_at`) and in its output
file `<id>.out`; both are kept ENDED_KEPT (a week: the owner back on Monday still
learns why Friday's session ended), at most ENDED_PER_OWNER per owner, and removed
by the owner's next listing after that.  A record whose process is gone without
saying so (SIGKILL, a crash, a power cut) is marked ended by the first listing that
may write it.  Ids are never reused while a record, socket or output file of theirs
is there: a new session's number is one more than any of its owner's.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import tempfile
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

from quadtank_tui.files.proc import pid_alive
from quadtank_tui.files.shared import read_untrusted
from quadtank_tui.session.info import SessionInfo

#: How long an ended session's record and output file are kept, and how many per owner.
ENDED_KEPT = timedelta(days=7)
ENDED_PER_OWNER = 20
#: Entries of a runtime folder looked at by a listing (a folder of a million junk
#: files costs a bounded time).
MAX_ENTRIES = 20000

class NoSession(LookupError):
    """No session matches what was asked; the message says what there is."""


def runtime_dir(configured: Path | None = None) -> Path:
    """The runtime folder (`configured`, else the lab configuration's), created
    sticky and world-writable (1777) if missing."""
    from quadtank_tui.session.lab import ensure_shared_dir, load_lab_config
    from quadtank_tui.session.roles import is_administrator

    lab = load_lab_config()
    return ensure_shared_dir(configured or lab.runtime_dir, trusted=lambda uid: is_administrator(uid, lab))


#: A session id: its owner's name (letters, digits, '_', '.', '-'; never "..") and
#: a number.  Every path of a session is its folder and this id, so an id that does
#: not match names nothing (a record saying "../victim/b" is no record).
SESSION_ID = re.compile(r"(?!.*\.\.)[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}-[0-9]{1,9}")
#: A record is a few hundred bytes; a file larger than this is no record.
MAX_RECORD = 64 * 1024


def valid_id(session_id: str) -> bool:
    """Whether `session_id` may be a session id (SESSION_ID): no '/', no '..'."""
    return isinstance(session_id, str) and SESSION_ID.fullmatch(session_id) is not None


def id_name(user: str) -> str:
    """A user name as the first part of a session id: any other character '_'."""
    name = re.sub(r"[^A-Za-z0-9_.-]", "_", user).replace("..", "__")[:64]
    return name if name and name[0] not in ".-" else "_" + name[:63]


def record_path(runtime: Path, session_id: str) -> Path:
    return runtime / f"{session_id}.json"


def socket_path(runtime: Path, session_id: str) -> Path:
    return runtime / f"{session_id}.sock"


def out_path(runtime: Path, session_id: str) -> Path:
    """The session's output file: its stderr and stdout, the reason it ended."""
    return runtime / f"{session_id}.out"


def claim_id(runtime: Path, user: str) -> str:
    """A new session id, `<user>-<n>`, n one more than any of `user`'s sessions whose
    files are still there (running or ended): an id a client, a record or an
    output file may still name is never given to another session.  Claimed by
    creating its record (O_EXCL: two sessions starting at once get different ids)."""
    list_sessions(runtime)  # marks the dead ones ended, removes the old ones
    user = id_name(user)
    own = re.compile(re.escape(user) + r"-([0-9]{1,9})\.(?:json|sock|out)")
    n = 1 + max((int(m.group(1)) for p in runtime.iterdir() if (m := own.fullmatch(p.name))), default=0)
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


def read_record(runtime: Path, session_id: str) -> SessionInfo | None:
    """The record of `session_id` in `runtime`; None if there is none or it is not
    one (being claimed, garbage, not a regular file, larger than MAX_RECORD, a
    record of another id).  Opened as read_untrusted does: a FIFO, a link to
    /dev/zero or a huge file there costs one open and one fstat.  Its socket is
    where the folder and the id say, whatever the file says."""
    if not valid_id(session_id):
        return None
    try:
        data, _ = read_untrusted(record_path(runtime, session_id), MAX_RECORD)
        obj = json.loads(data)
    except (OSError, ValueError, RecursionError):
        return None
    info = record_from(obj)
    if info is None or info.id != session_id:
        return None
    return dataclasses.replace(info, socket=str(socket_path(runtime, session_id)))


def record_from(obj: object) -> SessionInfo | None:
    """A SessionInfo from a record's JSON object if every field it has is of the
    type SessionInfo says (unknown keys dropped); None otherwise."""
    if not isinstance(obj, dict):
        return None
    values: dict[str, Any] = {}
    for f in dataclasses.fields(SessionInfo):
        if f.name not in obj:
            continue
        v = obj[f.name]
        want = _FIELD_TYPES[f.name]
        if type(v) is not want:  # bool is no int here, nor an int a bool
            return None
        values[f.name] = v
    try:
        return SessionInfo(**values)
    except TypeError:  # a required field missing
        return None


_FIELD_TYPES = {f.name: {"str": str, "int": int, "bool": bool}[str(f.type)] for f in dataclasses.fields(SessionInfo)}


def remove_files(runtime: Path, session_id: str, *, output: bool = False) -> None:
    """The session's socket and record (`output`: and its output file)."""
    paths = [socket_path(runtime, session_id), record_path(runtime, session_id)]
    for path in paths + ([out_path(runtime, session_id)] if output else []):
        try:
            path.unlink()
        except FileNotFoundError:
            pass
        except PermissionError:
            pass  # another user's files in a sticky folder: theirs to remove


def end_record(runtime: Path, info: SessionInfo, reason: str) -> SessionInfo:
    """Mark the session ended for `reason` (its record says so and when; its socket
    goes); the record as written."""
    ended = dataclasses.replace(info, ended=reason or "stopped", clients=0, operator="",
                                ended_at=datetime.now().isoformat(timespec="seconds"))
    try:
        socket_path(runtime, info.id).unlink()
    except OSError:
        pass
    try:
        write_record(runtime, ended)
    except OSError:
        pass  # not ours to write (another user's dead session): listed as ended all the same
    return ended


def died(info: SessionInfo) -> str:
    """What a record whose process is gone without a word says happened."""
    return (f"the session process (pid {info.pid}) was gone without stopping in order (killed, "
            "crashed, or the machine went down); pumps and log as it left them")


def _records(runtime: Path, *, prune: bool) -> list[SessionInfo]:
    """Every record, those of dead processes marked ended; `prune`: ended ones past
    ENDED_KEPT or past the owner's newest ENDED_PER_OWNER removed (when ours to remove)."""
    records = []
    for sid in _record_ids(runtime):
        info = read_record(runtime, sid)
        if info is None:
            continue
        if not info.ended and not pid_alive(info.pid):
            info = end_record(runtime, info, died(info)) if prune else \
                dataclasses.replace(info, ended=died(info), clients=0, operator="")
        records.append(info)
    if prune:
        kept: list[SessionInfo] = []
        oldest = (datetime.now() - ENDED_KEPT).isoformat(timespec="seconds")
        per_owner: dict[int, int] = {}
        for info in sorted(records, key=lambda i: (i.ended_at or i.started, i.id), reverse=True):
            if info.ended:
                per_owner[info.uid] = per_owner.get(info.uid, 0) + 1
                if (info.ended_at or info.started) < oldest or per_owner[info.uid] > ENDED_PER_OWNER:
                    remove_files(runtime, info.id, output=True)
                    continue
            kept.append(info)
        records = kept
    return records


def _record_ids(runtime: Path) -> list[str]:
    """The ids of the records in `runtime` (the names `<id>.json` with a valid id),
    at most MAX_ENTRIES names looked at."""
    out = []
    try:
        with os.scandir(runtime) as entries:
            for n, entry in enumerate(entries):
                if n >= MAX_ENTRIES:
                    break
                name = entry.name
                if name.endswith(".json") and valid_id(name[:-5]):
                    out.append(name[:-5])
    except OSError:
        return []
    return sorted(out)


def list_sessions(runtime: Path, *, prune: bool = True) -> list[SessionInfo]:
    """The live sessions, oldest first (`prune`: see _records)."""
    out = [i for i in _records(runtime, prune=prune) if not i.ended]
    out.sort(key=lambda i: (i.started, i.id))
    return out


def ended_sessions(runtime: Path) -> list[SessionInfo]:
    """The sessions that ended within ENDED_KEPT, newest first, each saying why."""
    out = [i for i in _records(runtime, prune=True) if i.ended]
    out.sort(key=lambda i: (i.ended_at or i.started, i.id), reverse=True)
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
