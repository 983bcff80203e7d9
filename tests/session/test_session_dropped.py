"""A client the session drops is told why, and leaves the pumps alone: the session
runs on and keeps driving them (before: the client heard the connection close,
took it for the session's death and commanded the pumps to 0 over a link of its
own - two writers to the rig - and told the student the session had stopped).

The host runs on a thread (sessionkit.ThreadSession); the rescue itself is a spy
here (the thread session has no DAQ): tests/daq/test_session_rig.py has the real
rig, the real session process, and the rescue of a session that died.
"""

from __future__ import annotations

import time
from typing import Callable

import pytest
from sessionkit import ThreadSession
from textual.widgets import Static

from quadtank_tui.commands.sessions import after_the_screen
from quadtank_tui.engine import commands as c
from quadtank_tui.session.client import SessionClient
from quadtank_tui.session.protocol import Dropped, Hello, decode, encode
from quadtank_tui.session.server import MAX_LINE_BURST, MAX_LINE_RATE
from quadtank_tui.ui.app import build_app
from quadtank_tui.ui.windows.base import ConfirmWindow

FLOOD = f"it sent lines faster than {MAX_LINE_RATE:g} a second (beyond a burst of {MAX_LINE_BURST})"


@pytest.fixture
def rescues(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The session ids whose pumps a client commanded to 0."""
    called: list[str] = []
    monkeypatch.setattr(SessionClient, "_pumps_to_zero", lambda self: called.append(self.info.id))
    return called


def flood(client: SessionClient) -> None:
    """Lines as fast as it can write them, until the session hangs up: a repeated
    Hello, which the session reads and ignores at once (an operator's Submits are
    each applied and answered with an update: on a loaded machine the session may
    read them slower than the rate that drops a client; only the rate decides)."""
    burst = encode(Hello("operator", "tui")) * 400
    deadline = time.monotonic() + 10.0
    try:
        while not client.gone and time.monotonic() < deadline:
            client._sock.sendall(burst)
    except OSError:
        pass


def bad_line(client: SessionClient) -> None:
    client._sock.sendall(b"this is not JSON\n")


def _drop(s: ThreadSession, poll, misbehave: Callable[[SessionClient], None]) -> SessionClient:
    """The owner's running session drops its screen for `misbehave`, and runs on."""
    client = SessionClient(s.path)
    assert client.submit(c.SetState("Run")).result(30).ok
    misbehave(client)
    assert client.wait_gone(30)
    _running(s, poll)
    return client


def _running(s: ThreadSession, poll) -> None:
    """The session samples on, and its owner drives it."""
    k = s.engine.snapshot().k
    assert poll(lambda: s.engine.snapshot().k > k + 5, 30.0)
    assert s.thread.is_alive() and s.reason is None
    with SessionClient(s.path) as again:
        assert again.role == "operator" and again.submit(c.SetState("Pause")).result(30).ok


@pytest.mark.parametrize(("misbehave", "reason"), [
    (flood, FLOOD),
    (bad_line, "it sent a line that is not a message of the session's protocol (not JSON: "),
], ids=["flood", "bad line"])
def test_a_dropped_operator_is_told_why_and_leaves_the_pumps_to_the_session(
        thread_session, poll, rescues, misbehave, reason, capsys) -> None:
    s: ThreadSession = thread_session(speed=20.0)
    with _drop(s, poll, misbehave) as client:
        assert rescues == [] and client.rescue is None and client.ended is None
        assert client.dropped is not None and client.dropped.startswith(reason), client.dropped
        noted = [line for line in capsys.readouterr().err.splitlines() if " dropped " in line]
        assert len(noted) == 1 and noted[0].endswith(f": {client.dropped}"), noted  # the session's output says why
        fault = client.snapshot().fault or ""
        assert fault == (f"session alice-1 dropped this screen ({client.dropped}) and runs on: "
                         "quadtank attach alice-1 comes back to it")
        assert client.submit(c.SetState("Pause")).result(5).message == "session alice-1 is gone"
        assert after_the_screen(client, None) == (f"quadtank: session alice-1 dropped this screen ({client.dropped}); "
                                                  "it keeps running: quadtank attach alice-1 comes back to it")


def test_dropped_is_the_last_line_after_the_line_it_was_receiving(thread_session) -> None:
    """On the wire: whole lines, then Dropped; the socket is closed after it."""
    s: ThreadSession = thread_session(speed=20.0)
    client = SessionClient(s.path)
    try:
        client._read_lock.acquire()  # the client's reader stops at the lock: the bytes are ours
        bad_line(client)
        data = bytes(client._reader._buf)  # the start of a line it had read
        client._sock.settimeout(10)
        while chunk := client._sock.recv(1 << 20):
            data += chunk
        lines = data.split(b"\n")
        assert lines[-1] == b""  # nothing cut off
        assert all(decode(line) is not None for line in lines[:-1])
        last = decode(lines[-2])
        assert isinstance(last, Dropped) and last.reason.startswith("it sent a line that is not a message")
    finally:
        client._read_lock.release()
        client.close()


def test_a_connection_closed_without_a_word_while_the_session_answers_is_no_death(
        thread_session, poll, rescues, monkeypatch: pytest.MonkeyPatch) -> None:
    """A session older than Dropped (or a farewell the client did not read in time)
    closes the connection without a word: the session still answers on its socket,
    so the client does not rescue it."""
    from quadtank_tui.session import server as server_module

    real_drop = server_module.Server.drop  # an older session's: no word to the dropped
    monkeypatch.setattr(server_module.Server, "drop", lambda self, conn, why=None: real_drop(self, conn))
    s: ThreadSession = thread_session(speed=20.0)
    with _drop(s, poll, bad_line) as client:
        assert rescues == []
        assert client.dropped == "its connection closed without a word"


async def test_the_screen_says_it_was_dropped_and_exit_only_leaves(thread_session, rescues) -> None:
    """One sentence on the session line, and Exit says the session runs on (never
    "has ended", never an offer to stop it)."""
    s: ThreadSession = thread_session(speed=1.0)  # Textual's pilot waits for an idle process
    client = SessionClient(s.path)
    app = build_app(client, refresh_interval=0.05)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        bad_line(client)
        bar = app.main.query_one("#session-bar", Static)
        deadline = time.monotonic() + 60
        while "dropped this screen" not in str(bar.render()):
            assert time.monotonic() < deadline, str(bar.render())
            await pilot.pause(0.05)
        assert str(bar.render()).startswith(
            "session alice-1 dropped this screen (it sent a line that is not a message of the session's protocol")
        assert "runs on: quadtank attach alice-1 comes back to it" in str(bar.render())
        await pilot.press("q")
        await pilot.pause()
        assert isinstance(app.screen, ConfirmWindow)
        assert app.screen.question.startswith("Session alice-1 dropped this screen (it sent a line")
        assert app.screen.question.endswith("it runs on: quadtank attach alice-1 comes back to it.\nExit?")
        await pilot.press("enter")
        await pilot.pause()
    assert not client.stop_on_close and rescues == []
    client.close()
    assert s.thread.is_alive() and s.reason is None


def test_a_screen_too_slow_to_read_is_dropped_and_leaves_the_pumps_alone(
        thread_session, poll, rescues, monkeypatch: pytest.MonkeyPatch) -> None:
    """A screen that stops reading (Ctrl-Z, a stalled link) falls MAX_BACKLOG behind
    and is dropped; its socket is full, so Dropped cannot reach it within the
    farewell's time (2 s; 0.2 here): when it reads again it finds the stream cut, and the session
    still answering on its socket tells it that it was dropped, not that the
    session died."""
    from quadtank_tui.session import server as server_module

    monkeypatch.setattr(server_module, "MAX_BACKLOG", 256 << 10)
    monkeypatch.setattr(server_module, "FAREWELL_TIMEOUT", 0.2)
    s: ThreadSession = thread_session(speed=200.0)
    client = SessionClient(s.path)
    try:
        assert client.submit(c.SetState("Run")).result(30).ok
        with client._read_lock:  # the screen stops reading
            assert poll(lambda: not any(conn.role == "operator" for conn in s.host.server.connections), 30.0)
            assert poll(lambda: not s.host.server._farewells, 10.0)  # the farewell gave up: the socket is closed
        assert client.wait_gone(30)
        k = s.engine.snapshot().k  # (no second screen: its history alone is past this small backlog)
        assert poll(lambda: s.engine.snapshot().k > k + 5, 30.0) and s.reason is None
        assert rescues == [] and client.rescue is None
        assert client.dropped in ("its connection closed without a word",
                                  "it fell too far behind in reading the session's updates")
    finally:
        client.close()
