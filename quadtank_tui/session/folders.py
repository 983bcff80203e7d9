"""The lab's shared runtime folder, laid out so that the operating system, not
what a file says, tells whose each thing is (issue 41).

    RUNTIME/            root's (or an administrator's), 1755: nobody else creates,
                        replaces or removes anything at this level
      users/            root's, 1777 sticky: each user makes a folder of their own
        UID/            theirs, 0755 (or 0700): their sessions' records, sockets,
                        output files; nobody else may plant, replace or remove
                        anything in it.  Taken by someone else first (a folder
                        named after another's uid): the owner makes UID.<hex>
      locks/            root's, 1777 sticky: the DAQ locks (session/lock.py)
      bookings/         root's, 1777 sticky: the rigs' bookings (session/bookings.py)

`quadtank lab init [FOLDER]` (an administrator, once, at installation) makes it.
A folder of a user's own (`$QUADTANK_RUNTIME` naming a folder that user made, as
the tests do) has the same layout with every part theirs (0755): a place for one
user's programs, which no other user trusts.

Where no lab folder was made - a fresh machine, `make run` - the default
runtime folder is not created by whoever comes first (a student's would be theirs
to shut or empty): each user gets a folder of their own instead,
`/tmp/quadtank-UID` (0700), where their own sessions and locks work as usual,
seen by nobody else (no teacher lists or takes over them, and the DAQ lock keeps
only that user's own programs apart; `quadtank lab` says so).

A folder counts as what it should be only by lstat (a real folder, not a link),
its owner and its mode; a place of a user's only if its owner is that uid and
no one else may write in it.
"""

from __future__ import annotations

import os
import pwd
import re
import secrets
import stat
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

#: A user's place in users/: their uid, or (that name taken by someone else) the uid and a suffix.
PLACE_NAME = re.compile(r"([0-9]{1,10})(?:\.[0-9a-f]{8})?")
#: Entries of users/ named as ignored by a listing (for `quadtank sessions`).
MAX_PLACES = 5000
#: Entries of one owner's in users/ looked at (a user has one place, two where
#: someone took their name first): junk costs its owner's entries only, counted
#: after lstat, so nobody's junk hides another's place.
MAX_PER_OWNER = 16


class RuntimeFolderError(OSError):
    """The runtime folder cannot be used as it is; the message says why and who fixes it."""


@dataclass(frozen=True)
class Root:
    """The runtime folder in force: `path`; `lab`: made for the lab (root's or an
    administrator's, shared), else one user's own; `note`: why it is not the one
    configured (no lab folder there yet), for `quadtank lab` to say."""

    path: Path
    lab: bool
    note: str = ""

    @property
    def users(self) -> Path:
        return self.path / "users"

    @property
    def locks(self) -> Path:
        return self.path / "locks"

    @property
    def bookings(self) -> Path:
        return self.path / "bookings"

    @property
    def shared(self) -> tuple[Path, Path, Path]:
        """The folders every user writes an entry of their own in (sticky in a lab's)."""
        return (self.users, self.locks, self.bookings)


@dataclass(frozen=True)
class Place:
    """One user's folder of sessions, and the uid the operating system says it is of."""

    path: Path
    uid: int


def _root_only(uid: int) -> bool:
    """Who administers when the caller does not say (session/lab.ensure_runtime_dir
    passes the lab's rule): root."""
    return uid == 0


def _name(uid: int) -> str:
    """The login name of `uid` (the number itself when it has none)."""
    try:
        return pwd.getpwuid(uid).pw_name
    except KeyError:
        return str(uid)


def personal_dir(uid: int | None = None) -> Path:
    """Where a user's sessions go when no lab folder was made: /tmp/quadtank-UID."""
    return Path(tempfile.gettempdir()) / f"quadtank-{os.getuid() if uid is None else uid}"


def _lstat(path: Path) -> os.stat_result | None:
    try:
        return os.lstat(path)
    except FileNotFoundError:
        return None


def _shut(st: os.stat_result) -> bool:
    """Nobody but the owner may write in it (no group or other write bit)."""
    return stat.S_IMODE(st.st_mode) & 0o022 == 0


def lab_folder(st: os.stat_result, admin: Callable[[int], bool] = _root_only) -> bool:
    """Whether a folder's lstat says it is the lab's: a real folder of root's or an
    administrator's that no one else may write in."""
    return stat.S_ISDIR(st.st_mode) and _shut(st) and (st.st_uid == 0 or admin(st.st_uid))


def unsafe_ancestor(folder: Path) -> str | None:
    """Why a folder above `folder` lets someone other than root or `folder`'s owner
    replace it (a folder of theirs, or one others may write in that is not sticky
    like /tmp); None if none does."""
    try:
        owner = os.lstat(folder).st_uid
    except OSError:
        return None
    for up in folder.absolute().parents:
        why = _unsafe_folder(up, owner)
        if why is not None:
            return f"{why} (above it)"
    return None


def _unsafe_folder(up: Path, owner: int) -> str | None:
    """Why the folder `up` lets someone other than root or `owner` replace what is in it."""
    try:
        st = os.stat(up)
    except OSError as exc:
        return f"{up}: {exc.strerror}"
    if st.st_uid not in (0, owner):
        return f"{up} is {_name(st.st_uid)}'s"
    if stat.S_IMODE(st.st_mode) & 0o022 and not st.st_mode & stat.S_ISVTX:
        return f"{up} may be written by others (mode {stat.S_IMODE(st.st_mode):o}, not sticky)"
    return None


def resolve(folder: Path, *, source: str = "named", admin: Callable[[int], bool] = _root_only) -> Root:
    """The runtime folder in force for `folder`, as configured from `source`
    ("lab file", "env", "named" or "default"), checked and, where it is ours to
    make, made.  RuntimeFolderError naming what is wrong and who may fix it."""
    me = os.getuid()
    admin_me = admin(me)
    st = _lstat(folder)
    if st is None:
        if source == "default":
            return _personal(f"{folder} was not made by an administrator (quadtank lab init)")
        if source == "lab file" and not admin_me:
            raise RuntimeFolderError(f"{folder}: the lab's runtime folder is not there; an administrator makes it "
                                     f"once with `quadtank lab init`")
        folder.mkdir(parents=True, exist_ok=True)
        os.chmod(folder, 0o1755 if admin_me else 0o755)
        st = os.lstat(folder)
    if not stat.S_ISDIR(st.st_mode):
        if source == "default":
            return _personal(f"{folder} is not a folder (a link or a file)")
        raise RuntimeFolderError(f"{folder}: the runtime folder is not a folder (a link or a file): "
                                 "an administrator may remove it and run `quadtank lab init`")
    if st.st_uid == me and not _shut(st) and source != "default":  # ours (an older version's 1777): ours alone
        os.chmod(folder, 0o1755 if admin_me else 0o755)
        st = os.lstat(folder)
    unsafe = unsafe_ancestor(folder)
    if lab_folder(st, admin) and unsafe is None:
        root = Root(folder, lab=True)
    elif st.st_uid == me and _shut(st):
        root = Root(folder, lab=False)
    elif source == "default":
        return _personal(unsafe or f"{folder} is {_name(st.st_uid)}'s with mode {stat.S_IMODE(st.st_mode):o}, "
                         "not a lab folder (quadtank lab init)")
    elif unsafe is not None:
        raise RuntimeFolderError(f"{folder}: not a lab folder: {unsafe}")
    else:
        raise RuntimeFolderError(
            f"{folder}: the runtime folder is {_name(st.st_uid)}'s with mode {stat.S_IMODE(st.st_mode):o}: "
            "not a lab folder (root's or an administrator's, writable by its owner only), so nothing in it "
            "can be trusted; an administrator makes it with `quadtank lab init " + str(folder) + "`")
    for sub in root.shared:
        _sub_folder(sub, root, st.st_uid)
    return root


def _personal(why: str) -> Root:
    """This user's own folder (no lab folder was made): /tmp/quadtank-UID, 0700."""
    folder = personal_dir()
    try:
        folder.mkdir(mode=0o700)
    except FileExistsError:
        pass
    st = os.lstat(folder)
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid():
        raise RuntimeFolderError(f"{folder}: your own runtime folder (there is no lab folder: {why}) is "
                                 f"{'not a folder' if not stat.S_ISDIR(st.st_mode) else _name(st.st_uid) + chr(39) + 's'}"
                                 "; an administrator may remove it, or make the lab's with `quadtank lab init`")
    if stat.S_IMODE(st.st_mode) & 0o077:
        os.chmod(folder, 0o700)
    root = Root(folder, lab=False, note=why)
    for sub in root.shared:
        _sub_folder(sub, root, os.getuid())
    return root


def _sub_folder(sub: Path, root: Root, owner: int) -> None:
    """users/ or locks/ of `root` (whose owner is `owner`): made by that owner (a
    lab's 1777 sticky, a user's own 0755); anything else there is refused."""
    mode = 0o1777 if root.lab else 0o755
    st = _lstat(sub)
    if st is None and os.getuid() == owner:
        try:
            sub.mkdir()
        except FileExistsError:
            pass
        else:
            os.chmod(sub, mode)
        st = _lstat(sub)
    if st is None:
        raise RuntimeFolderError(f"{sub}: missing in the lab's runtime folder; an administrator runs "
                                 f"`quadtank lab init {root.path}`")
    if stat.S_ISDIR(st.st_mode) and st.st_uid == owner and os.getuid() == owner and stat.S_IMODE(st.st_mode) != mode:
        os.chmod(sub, mode)
        st = os.lstat(sub)
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != owner or stat.S_IMODE(st.st_mode) != mode:
        what = "not a folder (a link or a file)" if not stat.S_ISDIR(st.st_mode) else \
            f"{_name(st.st_uid)}'s with mode {stat.S_IMODE(st.st_mode):o}"
        raise RuntimeFolderError(f"{sub}: {what}, not {_name(owner)}'s with mode {mode:o}; an administrator "
                                 f"runs `quadtank lab init {root.path}`")


# --- the users' places -------------------------------------------------------------------------


def place_ok(st: os.stat_result, uid: int) -> bool:
    """Whether an lstat says a folder is `uid`'s place: a real folder of that uid's
    in which no one else may write."""
    return stat.S_ISDIR(st.st_mode) and st.st_uid == uid and _shut(st)


def places(root: Path, ignored: list[tuple[str, str]] | None = None) -> list[Place]:
    """Every user's place in `root`/users, by uid then name (at most MAX_PER_OWNER
    entries of each owner's looked at); `ignored` gets (path, why) of (at most
    MAX_PLACES of) the entries that are not."""
    out: list[Place] = []
    per_owner: dict[int, int] = {}
    try:
        entries = os.scandir(root / "users")
    except OSError:
        return out
    with entries:
        for entry in entries:
            m = PLACE_NAME.fullmatch(entry.name)
            try:
                st = entry.stat(follow_symlinks=False)
            except OSError:
                continue
            per_owner[st.st_uid] = per_owner.get(st.st_uid, 0) + 1
            if per_owner[st.st_uid] > MAX_PER_OWNER:
                continue
            if m is not None and place_ok(st, int(m.group(1))):
                out.append(Place(Path(entry.path), int(m.group(1))))
            elif ignored is not None and len(ignored) < MAX_PLACES:
                ignored.append((entry.path, f"{entry.path}: not a user's folder of sessions ("
                                + ("not named after a uid" if m is None else
                                   f"{_name(st.st_uid)}'s, mode {stat.S_IMODE(st.st_mode):o}, named after "
                                   f"uid {m.group(1)}") + ")"))
    return sorted(out, key=lambda p: (p.uid, len(p.path.name), p.path.name))


def own_place(root: Path) -> Path:
    """This user's place in `root`/users, made (0755) if there is none: `UID`, or
    where someone else took that name first, `UID.<hex>`."""
    uid = os.getuid()
    mine = [p.path for p in places(root) if p.uid == uid]
    if mine:
        return mine[0]
    users = root / "users"
    path = users / str(uid)
    st = _lstat(path)
    if st is not None and stat.S_ISDIR(st.st_mode) and st.st_uid == uid:  # ours, with a mode others could write
        os.chmod(path, 0o755)
        return path
    if st is not None:
        path = users / f"{uid}.{secrets.token_hex(4)}"
    try:
        path.mkdir()
    except OSError as exc:
        raise RuntimeFolderError(f"{users}: cannot make your folder of sessions there ({exc.strerror}); "
                                 "an administrator runs `quadtank lab init`") from None
    os.chmod(path, 0o755)
    return path


# --- quadtank lab init -------------------------------------------------------------------------


def init_lab_folder(folder: Path) -> list[str]:
    """Make `folder` the lab's runtime folder (an administrator, once): the folder
    root's (when run by root; else its administrator's), 1755; users/, locks/ and
    bookings/ in it the same owner's, 1777 sticky.  A link or a file at any of the three
    names is removed first; a folder of someone else's is taken over (owner and
    mode), its entries kept (each counts only as its own owner's).  Returns what
    was done, a line each."""
    me = os.getuid()
    done: list[str] = []
    parent = folder.absolute().parent
    # every folder on the way judged for the caller, before anything is made (not
    # for the owner of the last one: a student's link there to a folder of root's
    # made the student's folders above it look like its owner's)
    on_the_way = [f for f in (parent, *parent.parents) if os.path.lexists(f)]
    up = next((why for why in (_unsafe_folder(f, me) for f in on_the_way) if why is not None), None)
    if up is not None:
        raise RuntimeFolderError(f"{folder}: a lab folder cannot be made there: {up}, so its owner could "
                                 "replace the lab folder; choose a folder under root's (e.g. /run/quadtank)")
    parent.mkdir(parents=True, exist_ok=True)
    for path, mode, what in ((folder, 0o1755, "the lab's runtime folder"),
                             (folder / "users", 0o1777, "each user makes a folder of sessions of their own here"),
                             (folder / "locks", 0o1777, "the DAQ locks"),
                             (folder / "bookings", 0o1777, "the rigs' bookings")):
        st = _lstat(path)
        if st is not None and not stat.S_ISDIR(st.st_mode):
            os.unlink(path)
            done.append(f"{path}: removed a {'link' if stat.S_ISLNK(st.st_mode) else 'file'} of "
                        f"{_name(st.st_uid)}'s there")
            st = None
        if st is None:
            path.mkdir(parents=path == folder, exist_ok=True)
        fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW)
        try:
            if me == 0:
                os.fchown(fd, 0, 0)
            os.fchmod(fd, mode)
        finally:
            os.close(fd)
        done.append(f"{path}: {_name(me)}'s, mode {mode:o} ({what})")
    return done
