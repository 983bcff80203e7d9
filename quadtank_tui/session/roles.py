"""Who is who: the administrator is defined by the operating system, never by a
password of ours.  With `admin_group` in the lab file, the members of that group
(and root) are administrators; without one, whoever may write the lab's defaults
(`default.par`, or the lab file itself) is.  A session learns who connects from the
kernel (SO_PEERCRED on its Unix socket), not from what the client says.

The user and group look-ups are module functions (`user_name`, `groups_of`,
`group_id`, `may_write`) so tests can stand in for other users.
"""

from __future__ import annotations

import grp
import os
import pwd
import socket
import stat
import struct
from dataclasses import dataclass
from pathlib import Path

from quadtank_tui.session.lab import LabConfig


class NotPermitted(PermissionError):
    """An action only an administrator may take; the message says who may."""


@dataclass(frozen=True)
class Peer:
    """A process on the machine: its user and group ids, pid and user name."""

    uid: int
    gid: int
    pid: int
    user: str


def user_name(uid: int) -> str:
    """The login name of `uid` (the number itself when it has none)."""
    try:
        return pwd.getpwuid(uid).pw_name
    except KeyError:
        return str(uid)


def groups_of(uid: int) -> set[int]:
    """Every group id `uid` belongs to: its primary group and the supplementary ones."""
    try:
        entry = pwd.getpwuid(uid)
    except KeyError:
        return set()
    return set(os.getgrouplist(entry.pw_name, entry.pw_gid)) | {entry.pw_gid}


def group_id(name: str) -> int | None:
    """The id of the group `name` (None: no such group on this machine)."""
    try:
        return grp.getgrnam(name).gr_gid
    except KeyError:
        return None


def may_write(uid: int, path: Path) -> bool:
    """Whether `uid` may write `path`, from its owner, group and mode bits (not
    os.access, which answers for this process, not for a peer)."""
    try:
        st = os.stat(path)
    except OSError:
        return False
    if uid == 0:
        return True
    if st.st_uid == uid:
        return bool(st.st_mode & stat.S_IWUSR)
    if st.st_gid in groups_of(uid):
        return bool(st.st_mode & stat.S_IWGRP)
    return bool(st.st_mode & stat.S_IWOTH)


def peer_of(sock: socket.socket) -> Peer:
    """The process at the other end of a connected Unix socket, from the kernel."""
    raw = sock.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, struct.calcsize("3i"))
    pid, uid, gid = struct.unpack("3i", raw)
    return Peer(uid=uid, gid=gid, pid=pid, user=user_name(uid))


def current_user() -> Peer:
    """This process, in the same shape as a peer."""
    uid = os.getuid()
    return Peer(uid=uid, gid=os.getgid(), pid=os.getpid(), user=user_name(uid))


def untrusted_lab_file(lab: LabConfig) -> str | None:
    """Why the lab file in use gives no one rights (None: it does, or there is
    none): only a file owned by root that no one else may write (but a group: the
    admin group it names, or any without one) says who administers; a student's own lab file with
    `admin_group: <their group>` made them one (issue 24)."""
    if lab.source is None:
        return None
    try:
        st = os.stat(lab.source)
    except OSError as exc:
        return f"the lab file {lab.source} cannot be checked ({exc.strerror})"
    if st.st_uid != 0:
        return f"the lab file {lab.source} is {user_name(st.st_uid)}'s, not root's, so it gives no one rights"
    # group-writable: by the admin group it names, or (none named) its writers administer
    group_ok = lab.admin_group is None or group_id(lab.admin_group) == st.st_gid
    if st.st_mode & stat.S_IWOTH or (st.st_mode & stat.S_IWGRP and not group_ok):
        return f"the lab file {lab.source} may be written by others, so it gives no one rights"
    return None


def _rules(lab: LabConfig) -> LabConfig:
    """`lab` as far as it may say who administers: an untrusted lab file's
    admin_group and defaults count for nothing (the installation's rule holds)."""
    if untrusted_lab_file(lab) is None:
        return lab
    return LabConfig(runtime_dir=lab.runtime_dir, share_group=lab.share_group, unattended=lab.unattended)


def defaults_of(lab: LabConfig) -> list[Path]:
    """What writing makes one an administrator when no group is configured:
    default.par (its folder while it does not exist) and the lab file in use."""
    lab = _rules(lab)
    par = lab.default_par if lab.default_par.exists() else lab.params_dir
    return [par] + ([lab.source] if lab.source is not None else [])


def is_administrator(uid: int, lab: LabConfig) -> bool:
    """Root, a member of the lab's admin group, or (no group configured) whoever
    may write the lab's defaults; a lab file root does not own decides nothing."""
    if uid == 0:
        return True
    lab = _rules(lab)
    if lab.admin_group is not None:
        gid = group_id(lab.admin_group)
        return gid is not None and gid in groups_of(uid)
    return any(may_write(uid, p) for p in defaults_of(lab))


def who_administers(lab: LabConfig) -> str:
    """Who the administrators are, for messages."""
    why = untrusted_lab_file(lab)
    if why is not None:
        return f"{who_administers(_rules(lab))}; {why}"
    if lab.admin_group is not None:
        missing = "" if group_id(lab.admin_group) is not None else ", which does not exist on this machine"
        return f"member of group {lab.admin_group}{missing}"
    return "someone who may write " + " or ".join(str(p) for p in defaults_of(lab))


def require_administrator(uid: int, lab: LabConfig, what: str) -> None:
    """NotPermitted naming what needs an administrator and who `uid` is."""
    if not is_administrator(uid, lab):
        raise NotPermitted(f"{what} needs an administrator ({who_administers(lab)}); you are {user_name(uid)}")
