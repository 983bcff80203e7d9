"""Where sessions live on the machine: one socket and one small JSON record each,
in their owner's folder of the runtime folder (session/folders.py: `users/UID/`,
made by that user, which nobody else may write in).

Nothing there is trusted for what it says (issue 41): a record counts for a user
only if it lies in their folder, its file is theirs, it names their uid, name and
an id of theirs (SESSION_ID: never a path), and its pid is a live process of that
uid (/proc).  Its socket is where the folder and the id say.  Files are read as
files.shared.read_untrusted does (no link followed, no FIFO waited on, at most
MAX_RECORD bytes).  A command that connects checks the socket's peer as well
(session/client.check_peer).

A session that ends says why in its record (`ended`, `ended_at`) and in its output
file `<id>.out`; both are kept ENDED_KEPT (a week: the owner back on Monday still
learns why Friday's session ended), at most ENDED_PER_OWNER per owner, and removed
by the owner's next listing after that.  A record whose process is gone without
saying so (SIGKILL, a crash, a power cut) is marked ended by its owner's next
listing; anyone else's lists it ended and writes nothing.  Ids are never reused
while a record, socket or output file of theirs is there: a new session's number
is one more than any of its owner's.
"""

from __future__ import annotations

import dataclasses
import json
import os
import pwd
import re
import tempfile
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

from quadtank_tui.files.proc import pid_alive, process_owner
from quadtank_tui.files.shared import Untrusted, read_untrusted
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
    """The runtime folder in force (`configured`, else the lab configuration's),
    checked and made where it is ours to make (session/folders.py): its users/
    holds each user's place."""
    from quadtank_tui.session.lab import ensure_runtime_dir, load_lab_config

    lab = load_lab_config()
    if configured is not None:
        lab = dataclasses.replace(lab, runtime_dir=configured, runtime_source="named")
    return ensure_runtime_dir(lab).path


#: A session id: its owner's name (letters, digits, '_', '.', '-'; never "..") and
#: a number.  Every path of a session is its folder and this id, so an id that does
#: not match names nothing (a record saying "../victim/b" is no record).
SESSION_ID = re.compile(r"(?!.*\.\.)[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}-[0-9]{1,9}")
#: A record is a few hundred bytes; a file larger than this is no record.
MAX_RECORD = 64 * 1024


def user_name(uid: int) -> str:
    """The login name of `uid` (the number itself when it has none): roles.user_name,
    without the lab file's modules a launcher need not load."""
    try:
        return pwd.getpwuid(uid).pw_name
    except KeyError:
        return str(uid)


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
    _place_records(runtime, os.getuid(), prune=True)  # marks the dead ones ended, removes the old ones
    user = id_name(user)
    own = re.compile(re.escape(user) + r"-([0-9]{1,9})\.(?:json|sock|out)")
    n = 1 + max((int(m.group(1)) for p in runtime.iterdir() if (m := own.fullmatch(p.name))), default=0)
    while True:
        sid = f"{user}-{n}"
        try:
            fd = os.open(record_path(runtime, sid), os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
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


@dataclasses.dataclass(frozen=True)
class Ignored:
    """A file in the runtime folder that is no one's record: what it is and why
    (for an administrator: `quadtank sessions` names them)."""

    path: str
    why: str


def read_record(runtime: Path, session_id: str) -> SessionInfo | None:
    """The record of `session_id` in `runtime` if the OS agrees with it (see
    checked_record); None otherwise."""
    info, _ = checked_record(runtime, session_id)
    return info


def checked_record(runtime: Path, session_id: str, uid: int | None = None) -> tuple[SessionInfo | None, str | None]:
    """(the record of `session_id` in `runtime`, None) if it is one and the OS
    agrees with what it says; else (None, why it is not, or None for a file that is
    merely no record yet: being claimed, gone meanwhile).

    Opened as read_untrusted does (a FIFO, a link to /dev/zero or a huge file there
    costs one open and one fstat).  It counts only if its file's owner is the uid
    it names (and, given, `uid`: the place's), its owner field is that uid's name and its id that name's; its socket
    is where the folder and the id say, whatever the file says.  Whether its pid is
    a process of that uid is the listing's to ask (it may have ended since)."""
    if not valid_id(session_id):
        return None, None
    path = record_path(runtime, session_id)
    try:
        data, st = read_untrusted(path, MAX_RECORD)
    except FileNotFoundError:
        return None, None
    except OSError as exc:
        return None, str(exc) if isinstance(exc, Untrusted) else f"{path}: {exc.strerror or exc}"
    if not data:
        return None, None  # claimed, not written yet
    try:
        obj = json.loads(data)
    except (ValueError, RecursionError):
        return None, f"{path}: not a session record (of {user_name(st.st_uid)})"
    info = record_from(obj)
    if info is None:
        return None, f"{path}: not a session record (of {user_name(st.st_uid)})"
    if info.uid != st.st_uid or (uid is not None and st.st_uid != uid):
        return None, f"{path}: written by {user_name(st.st_uid)}, says it is uid {info.uid}'s"
    name = user_name(info.uid)
    if info.owner != name or info.id != session_id or not session_id.startswith(id_name(name) + "-"):
        return None, f"{path}: written by {name}, names '{info.owner}' and session '{info.id}'"
    return dataclasses.replace(info, socket=str(socket_path(runtime, session_id))), None


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


def _records(root: Path, *, prune: bool, ignored: list[Ignored] | None = None) -> list[SessionInfo]:
    """Every user's records in the runtime folder `root` (each read from that user's
    place only: session/folders.places); see _place_records."""
    from quadtank_tui.session.folders import places

    found: list[tuple[str, str]] | None = [] if ignored is not None else None
    records: list[SessionInfo] = []
    for place in places(root, found):
        records += _place_records(place.path, place.uid, prune=prune, ignored=ignored)
    if ignored is not None and found:
        ignored[:0] = [Ignored(path, why) for path, why in found]
    return records


def _place_records(runtime: Path, uid: int, *, prune: bool, ignored: list[Ignored] | None = None
                   ) -> list[SessionInfo]:
    """The records in `uid`'s place `runtime` the OS agrees with (checked_record),
    those whose process is gone (or whose pid is now another user's process)
    ended; `prune` (our own place only): such records marked ended on disk, and
    the ended ones past ENDED_KEPT or past the newest ENDED_PER_OWNER removed.
    Nothing of another user's is ever written or removed.  `ignored` gets the
    files that are no one's record, and the records whose pid runs as someone else."""
    me = os.getuid()
    prune = prune and uid == me
    records = []
    bad: list[str] = []
    ids = _record_ids(runtime, bad)
    if ignored is not None:
        ignored.extend(Ignored(str(runtime / name), f"{runtime / name}: not a session id") for name in sorted(bad))
    for sid in ids:
        info, why = checked_record(runtime, sid, uid)
        if info is None:
            if why is not None and ignored is not None:
                ignored.append(Ignored(str(record_path(runtime, sid)), why))
            continue
        if not info.ended:
            runs_as = process_owner(info.pid) if pid_alive(info.pid) else None
            if runs_as != info.uid:
                if runs_as is not None and info.uid != me:  # a forgery, or a pid reused: not ours to say
                    if ignored is not None:
                        ignored.append(Ignored(str(record_path(runtime, sid)),
                                               f"{record_path(runtime, sid)}: names pid {info.pid}, a process of "
                                               f"{user_name(runs_as)}, not of {user_name(info.uid)}"))
                    continue
                info = end_record(runtime, info, died(info)) if prune else \
                    dataclasses.replace(info, ended=died(info), clients=0, operator="")
        records.append(info)
    if prune:
        kept: list[SessionInfo] = []
        oldest = (datetime.now() - ENDED_KEPT).isoformat(timespec="seconds")
        ended = 0
        for info in sorted(records, key=lambda i: (i.ended_at or i.started, i.id), reverse=True):
            if info.ended:
                ended += 1
                if (info.ended_at or info.started) < oldest or ended > ENDED_PER_OWNER:
                    remove_files(runtime, info.id, output=True)
                    continue
            kept.append(info)
        records = kept
    return records


def ignored_records(runtime: Path) -> list[Ignored]:
    """The entries of the runtime folder's users/ that are no one's place, the
    files of the places that are no one's record, and the records the OS
    disagrees with, each with why (for an administrator to look at)."""
    out: list[Ignored] = []
    _records(runtime, prune=False, ignored=out)
    return out


def _record_ids(runtime: Path, bad: list[str] | None = None) -> list[str]:
    """The ids of the records in `runtime` (the names `<id>.json` with a valid id),
    at most MAX_ENTRIES names looked at; `bad` gets the other `.json` names."""
    out = []
    try:
        with os.scandir(runtime) as entries:
            for n, entry in enumerate(entries):
                if n >= MAX_ENTRIES:
                    break
                name = entry.name
                if name.endswith(".json"):
                    if valid_id(name[:-5]):
                        out.append(name[:-5])
                    elif bad is not None:
                        bad.append(name)
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
