"""Sessions no other user can break (issue 24): a malformed line ends that
connection only; what a peer can make the session hold is bounded (line length,
nesting, time to say Hello); connections are limited per user and in total with a
reserve for the owner and the administrators.

The host runs on a thread (sessionkit.ThreadSession, peers' user ids stood in);
the two-user and out-of-descriptors cases with real processes are in
test_session_peers.py.
"""

from __future__ import annotations

import os

import socket
import time

import pytest
from sessionkit import OWNER, STUDENT, TEACHER, ThreadSession

from quadtank_tui.engine import commands as c
from quadtank_tui.session import server as server_module
from quadtank_tui.session.client import SessionClient, SessionError, connect
from quadtank_tui.session.protocol import MAX_HELLO_LINE, ProtocolError, decode
from quadtank_tui.session.server import MAX_CONNECTIONS, MAX_PER_USER, RESERVED

#: Lines another user sent before any Hello that ended the whole session (TypeError,
#: RecursionError out of decode), and their kin.
MALFORMED = [
    b'{"@":"map","v":[[[1],2]]}',                      # an unhashable map key: TypeError
    b"[" * 200_000,                                    # RecursionError in the JSON parser
    b'{"@":"tuple","v":' + b"[" * 40 + b"]" * 40 + b"}",  # deeper than MAX_DEPTH
    b'{"@":"Hello","role":"admin"}',                  # a role that is none
    b'{"@":"Hello","role":"observer","take_over":{"@":"map","v":[]}}',
    b'{"@":"Hello","role":"observer","client":[1,2]}',
    b'{"@":"Submit","id":1,"command":{"@":"SetParams","values":{"@":"map","v":[[{"@":"map","v":[]},1]]}}}',
    b'{"@":"enum","t":"Role","v":[[1]]}',
    b"\xff\xfe" + b"\x00" * 100,
]


def _raw(s: ThreadSession) -> socket.socket:
    sock = socket.socket(socket.AF_UNIX)
    sock.settimeout(10)
    connect(sock, s.path, 10)  # the backlog may be full for a moment: tries again
    return sock


def _hung_up(sock: socket.socket) -> bool:
    """The session closed this connection (whatever it said first)."""
    try:
        while sock.recv(1 << 16):
            pass
    except (ConnectionResetError, BrokenPipeError):
        pass
    return True


@pytest.mark.parametrize("line", MALFORMED, ids=lambda b: repr(b[:30]))
def test_decode_turns_any_malformed_line_into_a_protocol_error(line: bytes) -> None:
    with pytest.raises(ProtocolError):
        decode(line)


def test_a_malformed_line_from_another_user_ends_that_connection_only(thread_session, poll) -> None:
    """bob sends each line before (and after) his Hello: each time his connection is
    dropped, the session runs on and alice drives it."""
    s: ThreadSession = thread_session(speed=500.0)
    with SessionClient(s.path) as alice:
        assert alice.submit(c.SetState("Run")).result(30).ok
        for line in MALFORMED:
            s.peers.queue.append(STUDENT)
            raw = _raw(s)
            try:
                raw.sendall(line + b"\n")
            except (BrokenPipeError, ConnectionResetError):
                pass
            assert _hung_up(raw)
            raw.close()
        k = s.engine.snapshot().k
        assert poll(lambda: s.engine.snapshot().k > k + 10, 30.0)
        assert s.thread.is_alive() and s.reason is None
        assert alice.submit(c.SetState("Pause")).result(30).ok
        assert not alice.gone


def test_a_line_without_a_newline_is_bounded_before_hello(thread_session) -> None:
    """A peer that has not said Hello may make the session hold MAX_HELLO_LINE bytes,
    not the megabyte that 900 connections turned into 969 MB."""
    s: ThreadSession = thread_session()
    s.peers.queue.append(STUDENT)
    raw = _raw(s)
    sent = 0
    try:
        for _ in range(64):
            raw.sendall(b"x" * 1024)
            sent += 1024
    except (BrokenPipeError, ConnectionResetError):
        pass
    assert _hung_up(raw)
    assert sent <= 64 * 1024 and MAX_HELLO_LINE <= 4096
    assert all(conn.reader.held <= MAX_HELLO_LINE for conn in s.host.server.connections)
    raw.close()
    with SessionClient(s.path) as alice:
        assert alice.submit(c.SetState("Run")).result(30).ok


def test_a_peer_that_never_says_hello_is_dropped(thread_session, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(server_module, "HELLO_TIMEOUT", 0.3)
    s: ThreadSession = thread_session()
    s.peers.queue.append(STUDENT)
    raw = _raw(s)
    t0 = time.monotonic()
    assert raw.recv(100) == b""
    assert time.monotonic() - t0 < 5.0
    raw.close()


def test_connections_are_limited_per_user_and_in_total_with_room_for_owner_and_admins(
        thread_session, poll) -> None:
    """bob holds MAX_PER_USER connections and no more (the next is told why); other
    users fill the room they may use; the owner and an administrator still attach."""
    s: ThreadSession = thread_session()
    held: list[socket.socket] = []
    try:
        s.peers.queue.extend([STUDENT] * (MAX_PER_USER + 1))
        held += [_raw(s) for _ in range(MAX_PER_USER + 1)]
        assert poll(lambda: not s.peers.queue, 30.0)
        refused = held.pop()
        said = refused.recv(1000)
        assert b"Refused" in said and f"bob has {MAX_PER_USER} connections to this session already".encode() in said
        refused.close()
        # Other users up to the room left to them: MAX_CONNECTIONS - RESERVED in all.
        others = MAX_CONNECTIONS - RESERVED - MAX_PER_USER
        uids = [3000 + i // MAX_PER_USER for i in range(others + 1)]
        s.peers.queue.extend(uids)
        held += [_raw(s) for _ in uids]
        assert poll(lambda: not s.peers.queue, 30.0)
        last = held.pop()
        assert b"kept for its owner and the administrators" in last.recv(1000)
        last.close()
        assert poll(lambda: len(s.host.server.connections) == MAX_CONNECTIONS - RESERVED, 30.0)
        with SessionClient(s.path) as alice:            # the owner
            assert alice.submit(c.SetState("Run")).result(30).ok
            s.peers.queue.append(TEACHER)
            with SessionClient(s.path, role="observer") as teacher:  # an administrator
                assert teacher.role == "observer"
            s.peers.queue.append(3999)  # yet another user: no room
            with pytest.raises(SessionError, match="kept for its owner"):
                SessionClient(s.path, role="observer")
    finally:
        for sock in held:
            sock.close()
    # Once they are gone, the room is back.
    assert poll(lambda: len(s.host.server.connections) == 0, 30.0)
    s.peers.queue.append(STUDENT)
    raw = _raw(s)
    raw.close()
    assert s.thread.is_alive() and OWNER == s.host.access.owner_uid


def test_a_session_id_is_never_given_again_while_its_record_is_there(tmp_path) -> None:
    """alice-1 stopped (its record says so) and alice-2 died (SIGKILL: a stale
    record): the next session is alice-3, not the smallest number free of a
    running session (root-1 named another user's new session while its old
    client still offered to stop it)."""
    import subprocess

    from quadtank_tui.session.info import SessionInfo
    from quadtank_tui.session.runtime import claim_id, end_record, ended_sessions, user_name, write_record

    root = tmp_path / "run"
    runtime = root / "users" / str(os.getuid())  # this user's place in the runtime folder
    runtime.mkdir(parents=True)
    gone = subprocess.Popen(["true"])
    gone.wait()
    me = user_name(os.getuid())  # records count only as their file's owner's
    first = SessionInfo(id=f"{me}-1", owner=me, uid=os.getuid(), pid=gone.pid, started="2026-11-26T10:00:00",
                        plant="quadtank")
    end_record(runtime, first, "stopped by teacher")
    write_record(runtime, SessionInfo(id=f"{me}-2", owner=me, uid=os.getuid(), pid=gone.pid,
                                      started="2026-11-26T11:00:00", plant="quadtank"))
    assert claim_id(runtime, me) == f"{me}-3"
    assert claim_id(runtime, me) == f"{me}-4"  # claimed: its record exists
    assert claim_id(runtime, "bob") == "bob-1"
    ended = {i.id: i.ended for i in ended_sessions(root)}
    assert ended[f"{me}-1"] == "stopped by teacher"
    assert ended[f"{me}-2"].startswith(f"the session process (pid {gone.pid}) was gone without stopping in order")


def test_observers_that_never_read_hold_a_bounded_share_of_memory(thread_session, poll,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """bob may observe (a share group) and opens observers that never read: what the
    session queues for them together stays under MAX_BACKLOG_OTHERS (here 2 MB); the
    ones past it are dropped, the owner's client is not."""
    from quadtank_tui.session.protocol import Hello, encode

    monkeypatch.setattr(server_module, "MAX_BACKLOG_OTHERS", 2 << 20)
    s: ThreadSession = thread_session(speed=1000.0)
    s.host.access._may_connect = lambda uid: True  # everyone may observe
    with SessionClient(s.path) as alice:
        assert alice.submit(c.SetState("Run")).result(30).ok
        s.peers.queue.extend([STUDENT] * 8)
        silent = [_raw(s) for _ in range(8)]
        for sock in silent:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            sock.sendall(encode(Hello("observer")))
        server = s.host.server
        assert poll(lambda: not s.peers.queue, 30.0)  # all accepted
        welcomed = [conn for conn in server.connections if conn.rank == "other"]
        assert poll(lambda: any(conn not in server.connections for conn in welcomed), 60.0)
        others = [conn for conn in server.connections if conn.rank == "other"]
        assert server._others_queued == sum(len(conn.out) for conn in others) <= 2 << 20
        assert not alice.gone and alice.submit(c.SetState("Pause")).result(30).ok
        for sock in silent:
            sock.close()
