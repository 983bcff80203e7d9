"""Connection churn (issue 41, item 9): a user who connects, sends a bad line and
hangs up in a loop costs the session a bounded share of each event-loop turn,
is refused past a rate, and is named in the session's output once a minute, not
once a connection.  The 30-second churn against real sessions is
benchmarks/socket_churn.py.
"""

from __future__ import annotations

import asyncio
import socket
from pathlib import Path

import pytest
from sessionkit import OWNER, STUDENT, ThreadSession

from quadtank_tui.engine import commands as c
from quadtank_tui.session import server as server_module
from quadtank_tui.session.client import SessionClient, connect
from quadtank_tui.session.roles import Peer
from quadtank_tui.session.server import (
    ACCEPTS_PER_TURN, MAX_CONNECT_BURST, MAX_CONNECT_RATE, Server, listen,
)

#: A third user, so that the output is checked for one line per user.
CAROL = 3001


def _bad_connection(path: Path) -> bool:
    """connect / send `{bad` / close, as the issue's attacker; whether it got in."""
    sock = socket.socket(socket.AF_UNIX)
    sock.settimeout(5)
    try:
        connect(sock, path, 30)  # the backlog may be full for a moment: tries again
        sock.send(b"{bad\n")
        return True
    except OSError:
        return False
    finally:
        sock.close()


def test_one_turn_accepts_a_bounded_number_of_connections(tmp_path: Path) -> None:
    """30 connections wait in the backlog: one turn takes ACCEPTS_PER_TURN at most
    (fewer if ACCEPT_TURN_TIME ran out), the next turns the rest, none lost."""
    aloop = asyncio.new_event_loop()
    path = str(tmp_path / "s.sock")
    server = Server(listen(path), aloop, lambda conn, m: None, lambda conn: None,
                    peer_of=lambda sock: Peer(uid=OWNER, gid=OWNER, pid=1, user="alice"))
    clients = []
    try:
        for _ in range(30):
            sock = socket.socket(socket.AF_UNIX)
            sock.connect(path)
            clients.append(sock)
        server._accept()
        assert 1 <= server.accepted <= ACCEPTS_PER_TURN and server.accepted == len(server.connections)
        turns = 1
        while server.accepted < 30 and turns < 100:
            before = server.accepted
            server._accept()
            assert 1 <= server.accepted - before <= ACCEPTS_PER_TURN
            turns += 1
        assert server.accepted == 30 and turns >= 30 / ACCEPTS_PER_TURN
        assert len(server.connections) == server_module.MAX_PER_USER  # the rest were told why and closed
    finally:
        server.close()
        for sock in clients:
            sock.close()
        aloop.close()


def test_a_burst_of_bad_connections_is_refused_past_a_rate_and_named_once_per_user(
        thread_session, poll, capsys: pytest.CaptureFixture[str]) -> None:
    """bob and carol each open 200 connections that send `{bad` and hang up, as fast
    as they can: the session samples on, its owner drives it, each was turned away
    past MAX_CONNECT_BURST, and the output names each of them once (then, at the
    end, how many more there were) instead of 400 lines."""
    s: ThreadSession = thread_session(speed=20.0)
    n = 200
    with SessionClient(s.path) as alice:
        assert alice.submit(c.SetState("Run")).result(30).ok
        k = s.engine.snapshot().k
        for uid in (STUDENT, CAROL):
            s.peers.queue.extend([uid] * n)
            for _ in range(n):
                _bad_connection(s.path)
        assert poll(lambda: s.host.server.accepted >= 2 * n + 1, 30.0)
        assert poll(lambda: s.engine.snapshot().k > k + 5, 30.0)
        assert s.thread.is_alive() and s.reason is None
        assert alice.submit(c.SetState("Pause")).result(30).ok and not alice.gone
        # Past the burst, far more were refused than the rate let in meanwhile.
        assert s.host.server.refused >= 2 * n - 2 * (MAX_CONNECT_BURST + MAX_CONNECT_RATE * 10)
    s.stop()
    err = capsys.readouterr().err.splitlines()
    for user in ("bob", str(CAROL)):  # carol has no name in sessionkit.NAMES
        summary = [line for line in err if f" {user}: " in line and " more connections turned away or dropped" in line]
        first = [line for line in err if line not in summary
                 and (f" dropped {user} (pid " in line or f" turned away {user} (pid " in line)]
        assert len(first) == 1, err
        assert first[0].endswith("it sent a line that is not a message of the session's protocol (not JSON: "
                                 "Expecting property name enclosed in double quotes: line 1 column 2 (char 1))")
        assert len(summary) == 1 and f"{n - 1} more connections" in summary[0], summary
    assert len(err) < 10, err
