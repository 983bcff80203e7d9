"""A record counts for a user only if the operating system says it is theirs
(issue 41, items 1 and 2): its file's owner, the real uid of its pid (/proc), and,
when a command connects, the socket's peer (SO_PEERCRED).  alice and bob are real
users (useradd, root only; removed after); their processes are `sleep`s and a tiny
listener run under their uids.  Root runs the listing and `quadtank stop`, as in
the issue."""

from __future__ import annotations

import json
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
import textwrap
import time
from pathlib import Path
from typing import Callable, Iterator

import pytest
from otherusers import made_users

from quadtank_tui.cli import main
from quadtank_tui.session.client import SessionError, check_peer
from quadtank_tui.session.folders import init_lab_folder
from quadtank_tui.session.info import SessionInfo
from quadtank_tui.session.runtime import (
    ended_sessions, find_session, ignored_records, list_sessions, record_path, socket_path,
)

pytestmark = pytest.mark.skipif(os.getuid() != 0 or shutil.which("useradd") is None, reason="needs root and useradd")

#: Answers every connection with the line a stopped session sends last.
FAKE_ENDED = """
import os, socket, sys
s = socket.socket(socket.AF_UNIX)
s.bind(sys.argv[1]); os.chmod(sys.argv[1], 0o666); s.listen(8)
print("listening", flush=True)
while True:
    c, _ = s.accept()
    c.sendall(b'{"@": "Ended", "reason": "stopped by root"}\\n')
    c.close()
"""


@pytest.fixture(scope="module")
def users() -> Iterator[tuple[pwd.struct_passwd, pwd.struct_passwd]]:
    with made_users(f"qto{os.getpid()}a", f"qto{os.getpid()}b") as (alice, bob):
        yield pwd.getpwnam(alice), pwd.getpwnam(bob)


def as_(user: pwd.struct_passwd) -> Callable[[], None]:
    def drop() -> None:
        os.setgroups([])
        os.setgid(user.pw_gid)
        os.setuid(user.pw_uid)
    return drop


@pytest.fixture
def procs() -> Iterator[Callable[..., subprocess.Popen[str]]]:
    started: list[subprocess.Popen[str]] = []

    def start(user: pwd.struct_passwd, *argv: str) -> subprocess.Popen[str]:
        p = subprocess.Popen(argv, preexec_fn=as_(user), stdout=subprocess.PIPE, text=True, cwd="/")
        started.append(p)
        return p

    yield start
    for p in started:
        p.kill()
        p.wait()


@pytest.fixture
def runtime(monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The lab's runtime folder as `quadtank lab init` makes it (tmp_path is root's,
    0700: out of the other users' reach)."""
    top = Path(tempfile.mkdtemp(prefix="qto-"))
    os.chmod(top, 0o755)
    folder = top / "rt"
    init_lab_folder(folder)
    monkeypatch.setenv("QUADTANK_RUNTIME", str(folder))
    yield folder
    shutil.rmtree(top, ignore_errors=True)


def place(runtime: Path, user: pwd.struct_passwd, name: str | None = None) -> Path:
    """`user`'s folder of sessions (made as that user's first program would: 0755)."""
    path = runtime / "users" / (name or str(user.pw_uid))
    path.mkdir(exist_ok=True)
    os.chown(path, user.pw_uid, user.pw_gid)
    os.chmod(path, 0o755)
    return path


def put(folder: Path, user: pwd.struct_passwd, name: str, **fields: object) -> Path:
    """A file `name`.json of `user`'s in `folder` holding a record (its own by default)."""
    sid = str(fields.get("id", name))
    rec = {"id": sid, "owner": user.pw_name, "uid": user.pw_uid, "pid": 1 << 22, "started": "2026-12-01T10:00:00",
           "plant": "quadtank", "operation": "Active", "state": "Run", "socket": "/tmp/elsewhere.sock", **fields}
    path = folder / f"{name}.json"
    path.write_text(json.dumps(rec))
    os.chown(path, user.pw_uid, user.pw_gid)
    return path


def own(folder: Path, user: pwd.struct_passwd, name: str, text: str = "bob's\n") -> Path:
    path = folder / name
    path.write_text(text)
    os.chown(path, user.pw_uid, user.pw_gid)
    return path


def test_a_forged_record_hides_no_live_session_and_deletes_nothing(runtime: Path, users, procs) -> None:
    """Before: alice's copy of bob-1's record with a dead pid made the next listing
    delete bob-1.sock and mark bob-1 'gone without stopping in order' (and `stop
    bob-1` answer 'no session'); a record saying `"id": "bob-2", "ended": ...`
    made root's listing delete the live bob-2's .sock, .json and .out.  Now alice
    writes only in her own folder, and what she writes there counts as hers only:
    a copy of bob's record, one naming bob's session, a folder named after bob's
    uid, files in the runtime folder itself - all ignored, named to root."""
    alice, bob = users
    live = procs(bob, "sleep", "60")
    place(runtime, alice, str(bob.pw_uid))  # alice took bob's folder name first
    bobs = place(runtime, bob, f"{bob.pw_uid}.0123abcd")  # (session/folders.own_place's answer to that)
    hers = place(runtime, alice)
    for n in ("1", "2"):
        put(bobs, bob, f"{bob.pw_name}-{n}", pid=live.pid)
        own(bobs, bob, f"{bob.pw_name}-{n}.sock")
        own(bobs, bob, f"{bob.pw_name}-{n}.out")
    before = {p.name: p.read_text() for p in bobs.iterdir()}
    put(hers, alice, "alice-forged-a", id=f"{bob.pw_name}-1", owner=bob.pw_name, uid=bob.pw_uid)
    put(hers, alice, f"{bob.pw_name}-1", owner=bob.pw_name, uid=bob.pw_uid)  # bob's record, copied
    put(hers, alice, f"{alice.pw_name}-7", id=f"{bob.pw_name}-2", ended="stopped", ended_at="2020-01-01T00:00:00")
    put(runtime / "users" / str(bob.pw_uid), alice, f"{bob.pw_name}-3", owner=bob.pw_name, uid=bob.pw_uid,
        ended="stopped", ended_at="2020-01-01T00:00:00")
    put(runtime, alice, f"{bob.pw_name}-4", owner=bob.pw_name, uid=bob.pw_uid)  # the old flat folder: not read
    assert [(i.id, i.socket) for i in list_sessions(runtime)] == [
        (f"{bob.pw_name}-{n}", str(bobs / f"{bob.pw_name}-{n}.sock")) for n in ("1", "2")]
    assert ended_sessions(runtime) == []
    assert {p.name: p.read_text() for p in bobs.iterdir()} == before
    assert find_session(runtime, f"{bob.pw_name}-1", 0).pid == live.pid
    whys = [i.why for i in ignored_records(runtime)]
    assert any(f"users/{bob.pw_uid}: not a user's folder of sessions ({alice.pw_name}'s, mode 755, named after "
               f"uid {bob.pw_uid})" in w for w in whys), whys
    assert any(f"{hers}/{bob.pw_name}-1.json: written by {alice.pw_name}, says it is uid {bob.pw_uid}'s" in w
               for w in whys), whys
    assert any(f"{alice.pw_name}-7.json: written by {alice.pw_name}, names '{alice.pw_name}' and session "
               f"'{bob.pw_name}-2'" in w for w in whys)
    assert any("alice-forged-a.json: not a session id" in w for w in whys)


def test_a_record_naming_another_users_process_is_ignored_and_nothing_is_written(runtime: Path, users,
                                                                                 procs) -> None:
    """bob's record naming alice's process counts for nothing (it is not his
    session); bob's record whose process died is listed ended by root's listing,
    and left as it is on disk: only bob's own listing writes or removes it."""
    alice, bob = users
    alices = procs(alice, "sleep", "60")
    bobs = place(runtime, bob)
    put(bobs, bob, f"{bob.pw_name}-1", pid=alices.pid)
    dead = put(bobs, bob, f"{bob.pw_name}-2")  # pid 1 << 22: no such process
    old = put(bobs, bob, f"{bob.pw_name}-3", ended="stopped by bob", ended_at="2020-01-01T00:00:00")
    texts = {p: p.read_text() for p in (dead, old)}
    assert list_sessions(runtime) == []
    assert [(i.id, i.ended.split(" (")[0]) for i in ended_sessions(runtime)] == [
        (f"{bob.pw_name}-2", "the session process"), (f"{bob.pw_name}-3", "stopped by bob")]
    assert {p: p.read_text() for p in (dead, old)} == texts
    (ignored,) = ignored_records(runtime)
    assert ignored.why.endswith(f"names pid {alices.pid}, a process of {alice.pw_name}, not of {bob.pw_name}")


def test_stop_is_not_fooled_by_a_socket_of_alices_answering_ended(runtime: Path, users, procs, capsys) -> None:
    """Before: a record naming alice's process and a socket of hers answering
    `Ended`: root's `quadtank stop bob-2` said 'session bob-2 stopped (stopped by
    root): pumps at 0' and exited 0 while bob's session ran on.  Now the socket's
    peer must be the record's pid and uid: refused before a byte is sent.  (alice
    cannot put a socket in bob's folder; here one of hers is moved there, as a
    socket bob's session left for another program would be.)"""
    alice, bob = users
    bobs_session = procs(bob, "sleep", "60")
    bobs = place(runtime, bob)
    sid = f"{bob.pw_name}-2"
    put(bobs, bob, sid, pid=bobs_session.pid)
    hers = runtime.parent / "alice"
    hers.mkdir()
    os.chown(hers, alice.pw_uid, alice.pw_gid)
    fake = procs(alice, "/usr/bin/python3", "-c", textwrap.dedent(FAKE_ENDED), str(hers / "s.sock"))
    assert fake.stdout is not None and fake.stdout.readline() == "listening\n"
    os.rename(hers / "s.sock", socket_path(bobs, sid))
    assert main(["stop", sid]) == 2
    err = capsys.readouterr().err
    assert f"is not session {sid}'s: it is answered by pid {fake.pid} of {alice.pw_name}" in err
    assert bobs_session.poll() is None and record_path(bobs, sid).exists()
@pytest.mark.wallclock
def test_check_peer_wants_the_records_pid_and_uid(tmp_path: Path) -> None:
    path = str(tmp_path / "s.sock")
    server = socket.socket(socket.AF_UNIX)
    server.bind(path)
    server.listen(1)
    me = SessionInfo(id="x-1", owner="x", uid=os.getuid(), pid=os.getpid(), started="", plant="quadtank")
    try:
        for expect, ok in ((me, True), (None, True), (SessionInfo(**{**me.__dict__, "pid": 1}), False),
                           (SessionInfo(**{**me.__dict__, "uid": 4242}), False)):
            c = socket.socket(socket.AF_UNIX)
            c.connect(path)
            try:
                if ok:
                    check_peer(c, path, expect)
                else:
                    with pytest.raises(SessionError, match=f"answered by pid {os.getpid()}"):
                        check_peer(c, path, expect)
            finally:
                c.close()
                server.accept()[0].close()
    finally:
        server.close()
    time.sleep(0)
