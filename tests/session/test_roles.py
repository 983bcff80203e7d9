"""Roles: administrators by group membership or by write access to the lab's
defaults; peers identified by the kernel.  Other users are simulated by standing
in for the look-ups (roles.user_name, groups_of, group_id)."""

from __future__ import annotations

import os
import socket
from pathlib import Path

import pytest

from quadtank_tui.session import roles
from quadtank_tui.session.lab import DEFAULT_PARAMS_DIR, LabConfig
from quadtank_tui.session.roles import (
    NotPermitted, Peer, current_user, is_administrator, may_write, peer_of, require_administrator,
)

ME = os.getuid()
ALICE, BOB = 50001, 50002      # a teacher, a student
TEACHERS, STUDENTS = 60001, 60002


@pytest.fixture
def users(monkeypatch: pytest.MonkeyPatch) -> None:
    names = {ALICE: "alice", BOB: "bob", 0: "root"}
    groups = {ALICE: {STUDENTS, TEACHERS}, BOB: {STUDENTS}}
    monkeypatch.setattr(roles, "user_name", lambda uid: names.get(uid, str(uid)))
    monkeypatch.setattr(roles, "groups_of", lambda uid: groups.get(uid, set()))
    monkeypatch.setattr(roles, "group_id", {"teachers": TEACHERS, "students": STUDENTS}.get)


def test_admin_group_members_only(users: None) -> None:
    lab = LabConfig(admin_group="teachers")
    assert [is_administrator(u, lab) for u in (ALICE, BOB, 0)] == [True, False, True]
    require_administrator(ALICE, lab, "saving default.par")
    with pytest.raises(NotPermitted) as caught:
        require_administrator(BOB, lab, "saving default.par")
    assert str(caught.value) == ("saving default.par needs an administrator (member of group teachers); "
                                 "you are bob")


def test_a_group_missing_on_the_machine_makes_nobody_administrator(users: None) -> None:
    lab = LabConfig(admin_group="staff")
    assert not is_administrator(ALICE, lab)
    with pytest.raises(NotPermitted, match=r"\(member of group staff, which does not exist on this machine\)"):
        require_administrator(ALICE, lab, "taking over the rig")


def owned_by_a_user(path: Path) -> int:
    """A non-root owner of `path` (the tests may run as root, who may write anything):
    this user, or alice when the tests run as root."""
    if ME != 0:
        return ME
    os.chown(path, ALICE, TEACHERS)
    return ALICE


def test_without_a_group_whoever_may_write_the_defaults(users: None, tmp_path: Path) -> None:
    params = tmp_path / "params"
    params.mkdir()
    par = params / "default.par"
    par.write_text("% TANK PAR-file\n")
    owner = owned_by_a_user(par)
    lab = LabConfig(params_dir=params)
    os.chmod(par, 0o644)
    assert is_administrator(owner, lab)       # the owner with rw
    assert not is_administrator(BOB, lab)     # others: r only
    assert is_administrator(0, lab)           # root
    os.chmod(par, 0o444)
    assert not is_administrator(owner, lab)
    os.chmod(par, 0o646)
    assert is_administrator(BOB, lab)         # world-writable: everyone
    os.chmod(par, 0o644)
    with pytest.raises(NotPermitted, match=rf"\(someone who may write {par}\); you are bob"):
        require_administrator(BOB, lab, "setting the unattended policy")


def test_without_default_par_its_folder_counts(users: None, tmp_path: Path) -> None:
    params = tmp_path / "params"
    params.mkdir()
    owner = owned_by_a_user(params)
    os.chmod(params, 0o755)
    lab = LabConfig(params_dir=params)
    assert (is_administrator(owner, lab), is_administrator(BOB, lab)) == (True, False)


def test_may_write_reads_the_group_bits(users: None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "f"
    path.write_text("x")
    if ME == 0:
        os.chown(path, BOB, TEACHERS)
    gid = os.stat(path).st_gid
    carol = 50003  # neither the owner nor root
    monkeypatch.setattr(roles, "groups_of", lambda uid: {gid} if uid in (ALICE, carol) else set())
    os.chmod(path, 0o464)
    assert [may_write(u, path) for u in (carol, 50004, 0)] == [True, False, True]
    os.chmod(path, 0o644)
    assert not may_write(carol, path)
    assert not may_write(carol, tmp_path / "missing")


root_only = pytest.mark.skipif(ME != 0, reason="needs root (chown)")


@root_only
def test_lab_file_write_access_counts_too(users: None, tmp_path: Path) -> None:
    """Its group's members may write root's lab file: they administer; a file
    everyone may write gives no one rights."""
    source = tmp_path / "lab.yaml"
    source.write_text("")
    os.chown(source, 0, TEACHERS)
    os.chmod(source, 0o664)
    lab = LabConfig(params_dir=tmp_path / "none", source=source)
    assert [is_administrator(u, lab) for u in (ALICE, BOB)] == [True, False]
    os.chmod(source, 0o646)
    assert not is_administrator(BOB, lab)


@root_only
def test_a_students_own_lab_file_gives_no_rights(users: None, tmp_path: Path) -> None:
    """Issue 24: QUADTANK_LAB=mylab.yaml with `admin_group: <their group>` made a
    student an administrator (and `run --take-over` drove a rig beside its holder)."""
    source = tmp_path / "mylab.yaml"
    source.write_text("admin_group: students\n")
    os.chown(source, BOB, STUDENTS)
    os.chmod(source, 0o644)
    lab = LabConfig(admin_group="students", params_dir=tmp_path / "none", source=source)
    assert not is_administrator(BOB, lab) and is_administrator(0, lab)
    with pytest.raises(NotPermitted) as caught:
        require_administrator(BOB, lab, "taking over the rig")
    assert str(caught.value) == (f"taking over the rig needs an administrator (someone who may write "
                                 f"{DEFAULT_PARAMS_DIR / 'default.par'}; the lab file {source} is bob's, not root's, so it gives "
                                 "no one rights); you are bob")


def test_peer_of_a_socketpair_is_this_process() -> None:
    a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
    with a, b:
        assert peer_of(a) == current_user() == Peer(ME, os.getgid(), os.getpid(), roles.user_name(ME))


def test_peer_of_a_connecting_child_is_the_child(tmp_path: Path) -> None:
    """Through a listening socket, as a session sees a client: the kernel's pid,
    not one the client could claim."""
    path = str(tmp_path / "s.sock")
    server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    server.bind(path)
    server.listen(1)
    pid = os.fork()
    if pid == 0:  # the child: connect, wait to be read, leave
        try:
            c = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            c.connect(path)
            c.recv(1)
        finally:
            os._exit(0)
    try:
        conn, _ = server.accept()
        with conn:
            peer = peer_of(conn)
            conn.sendall(b"x")
    finally:
        server.close()
        os.waitpid(pid, 0)
    assert (peer.pid, peer.uid, peer.gid) == (pid, ME, os.getgid())


def test_the_real_lookups_for_a_system_user() -> None:
    """No stand-ins: the operating system's own user and group databases."""
    import grp
    import pwd

    try:
        nobody = pwd.getpwnam("nobody")
        group = grp.getgrgid(nobody.pw_gid).gr_name
    except KeyError:
        pytest.skip("no user 'nobody' on this machine")
    assert roles.user_name(nobody.pw_uid) == "nobody"
    assert nobody.pw_gid in roles.groups_of(nobody.pw_uid)
    assert roles.group_id(group) == nobody.pw_gid
    assert is_administrator(nobody.pw_uid, LabConfig(admin_group=group))
    assert not is_administrator(nobody.pw_uid, LabConfig(admin_group=grp.getgrgid(0).gr_name))
    assert roles.group_id("no-such-group-here") is None and roles.groups_of(2**31 - 2) == set()
    assert roles.user_name(2**31 - 2) == str(2**31 - 2)


@pytest.mark.skipif(ME != 0, reason="needs root (chown to another user)")
def test_a_params_folder_in_the_current_folder_makes_nobody_administrator(
        users: None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 24: stud1, without a lab file, in a folder of their own (whose
    params/default.par they may write) was 'administrator: yes'.  Without a lab
    file the installation's params/ decides (root's here), whoever runs where."""
    params = tmp_path / "params"
    params.mkdir()
    (params / "default.par").write_text("% TANK PAR-file\n")
    os.chown(params, ALICE, TEACHERS)
    os.chown(params / "default.par", ALICE, TEACHERS)
    monkeypatch.chdir(tmp_path)
    assert may_write(ALICE, Path("params/default.par"))
    lab = LabConfig()
    assert lab.params_dir == Path(roles.__file__).resolve().parents[2] / "params"
    assert not is_administrator(ALICE, lab)
