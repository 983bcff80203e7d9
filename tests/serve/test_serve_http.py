"""`quadtank serve` from outside, without a browser: every door without a login,
the login's answers, the cookie, the websocket's Origin, logout, and 100 wrong
passwords (issue 44).  A real server process, real users (PAM, useradd/chpasswd)."""

from __future__ import annotations

import asyncio
import os
import subprocess
import sys
import time
from typing import Iterator
from urllib.parse import urlencode

import aiohttp
import pytest
from servekit import ROOT, Serve, User, can_make_users, made_users, serving

pytestmark = [pytest.mark.wallclock, pytest.mark.skipif(can_make_users() is not None,
                                                        reason=str(can_make_users()))]


@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Serve, dict[str, User]]]:
    with serving() as server:
        homes = server.folder / "homes"
        homes.mkdir()
        with made_users(homes, "a", "b") as users:
            yield server, users


@pytest.fixture(scope="module")
def bobs_run(world: tuple[Serve, dict[str, User]]) -> subprocess.Popen[str]:
    """bob's detached run (a session of his), started when the module's first test
    asks for it and left to start while the tests that need no session run: the
    last test, which reads it, waits for it (a `quadtank` as another user takes 2-5 s)."""
    server, users = world
    bob = users["b"]
    env = {"PATH": os.environ.get("PATH", ""), "PYTHONPATH": str(ROOT), "HOME": str(bob.home),
           "QUADTANK_RUNTIME": str(server.runtime)}
    return subprocess.Popen(["runuser", "-u", bob.name, "--", sys.executable, "-m", "quadtank_tui", "run",
                             "--duration", "600", "--realtime", "--log", "bob.log", "--detach"],
                            cwd=bob.home, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


async def open_tab(server: Serve, cookie: str | None, path: str = "/ws", origin: str | None = "own"):
    """(status, websocket or None): the websocket's handshake as a browser makes it."""
    headers = {}
    if origin is not None:
        headers["Origin"] = server.origin if origin == "own" else origin
    if cookie:
        headers["Cookie"] = f"quadtank_session={cookie}"
    session = aiohttp.ClientSession()
    try:
        ws = await session.ws_connect(f"ws://127.0.0.1:{server.port}{path}?width=100&height=30", headers=headers)
    except aiohttp.WSServerHandshakeError as exc:
        await session.close()
        return exc.status, None, None
    return 101, ws, session


async def screen_text(ws: aiohttp.ClientWebSocketResponse, want: str, timeout: float) -> str:
    """The tab's screen bytes until `want` shows (or the tab closes, or `timeout`)."""
    got = b""
    deadline = time.monotonic() + timeout
    while want.encode() not in got:
        left = deadline - time.monotonic()
        if left <= 0:
            break
        try:
            msg = await ws.receive(timeout=left)
        except asyncio.TimeoutError:
            break
        if msg.type == aiohttp.WSMsgType.BINARY:
            got += msg.data
        elif msg.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED, aiohttp.WSMsgType.CLOSING):
            break
    return got.decode("utf-8", "replace")


def test_without_a_login_every_door_is_shut(world: tuple[Serve, dict[str, User]],
                                            bobs_run: subprocess.Popen[str]) -> None:
    server, _ = world
    status, headers, _ = server.request("GET", "/")
    assert (status, headers["location"]) == (303, "/login")
    for path in ("/static/js/textual.js", "/static/css/xterm.css", "/ws", "/ws/attach/x-1", "/nothing",
                 "/static/../../etc/passwd"):
        assert server.request("GET", path)[0] == 401, path
    assert server.request("POST", "/")[0] == 401
    status, _, page = server.request("GET", "/login")
    assert status == 200 and 'name="password"' in page
    # another Host (DNS rebinding) is not this server
    assert server.request("GET", "/login", headers={"Host": "evil.example:80"})[0] == 421
    assert asyncio.run(open_tab(server, None))[0] == 401


def test_a_wrong_password_and_an_unknown_user_get_the_same_answer(world: tuple[Serve, dict[str, User]]) -> None:
    server, users = world
    from concurrent.futures import ThreadPoolExecutor

    def attempt(name: str) -> tuple[int, str | None, float]:
        t0 = time.monotonic()
        status, cookie, _ = server.login(name, "not-the-password")
        return status, cookie, time.monotonic() - t0

    with ThreadPoolExecutor(2) as pool:  # side by side: the same answer, and half the wall time
        answers = list(pool.map(attempt, (users["b"].name, f"nobody{users['b'].name}")))
    assert [a[:2] for a in answers] == [(401, None), (401, None)]
    assert all(a[2] >= 1.0 for a in answers), answers  # each failure answered after 1 s at least
    lines = server.audit_lines()
    assert any(f"login-failed user={users['b'].name} " in line for line in lines), lines


def test_login_cookie_websocket_origin_and_logout(world: tuple[Serve, dict[str, User]]) -> None:
    server, users = world
    alice = users["a"]
    status, cookie, headers = server.login(alice.name, alice.password)
    assert status == 303 and headers["location"] == "/" and cookie
    attributes = {p.strip().split("=")[0].lower() for p in headers["set-cookie"].split(";")}
    assert {"httponly", "path", "samesite"} <= attributes and "secure" not in attributes  # plain http here
    assert "SameSite=Strict" in headers["set-cookie"]
    status, _, page = server.request("GET", "/", cookie=cookie)
    assert status == 200 and f'data-session-websocket-url="ws://127.0.0.1:{server.port}/ws"' in page
    assert server.request("GET", "/static/js/textual.js", cookie=cookie)[0] == 200

    async def tabs() -> str:
        assert (await open_tab(server, cookie, origin=None))[0] == 403
        assert (await open_tab(server, cookie, origin="http://evil.example"))[0] == 403
        assert (await open_tab(server, cookie, origin=f"http://localhost:{server.port + 1}"))[0] == 403
        status, ws, session = await open_tab(server, cookie)
        assert status == 101 and ws is not None and session is not None
        text = await screen_text(ws, "you operate", 40.0)
        await ws.close()
        await session.close()
        return text

    text = asyncio.run(tabs())
    # the Main screen, run as alice: her session, her the operator
    assert f"session {alice.name}-1 of {alice.name}" in text and "you operate" in text, text[-2000:]
    assert "Setup" in text and "Simul" in text
    stolen = cookie
    status, headers, _ = server.request("POST", "/logout", cookie=cookie, headers={"Origin": server.origin})
    assert (status, headers["location"]) == (303, "/login")
    assert server.request("GET", "/", cookie=stolen)[0] == 303
    assert server.request("GET", "/static/js/textual.js", cookie=stolen)[0] == 401
    assert asyncio.run(open_tab(server, stolen))[0] == 401
    lines = server.audit_lines()
    assert any(f"login user={alice.name} address=127.0.0.1 via=pam" in line for line in lines)
    assert any(f"logout user={alice.name}" in line for line in lines)
    assert any(f"websocket-refused user={alice.name}" in line and "origin=http://evil.example" in line
               for line in lines)


def test_100_wrong_passwords_are_slowed_and_the_account_still_works(world: tuple[Serve, dict[str, User]]) -> None:
    server, users = world
    bob = users["b"]

    async def guesses() -> list[int]:
        async with aiohttp.ClientSession() as session:
            async def one(i: int) -> int:
                async with session.post(f"{server.origin}/login", data=urlencode(
                        {"user": bob.name, "password": f"guess{i}"}),
                        headers={"Content-Type": "application/x-www-form-urlencoded"},
                        allow_redirects=False) as r:
                    return r.status
            return list(await asyncio.gather(*(one(i) for i in range(100))))

    t0 = time.monotonic()
    statuses = asyncio.run(guesses())
    elapsed = time.monotonic() - t0
    assert set(statuses) <= {401, 429} and statuses.count(401) <= 4, statuses  # few reach a password check
    assert elapsed < 15.0
    status, _, page = server.request("GET", "/login")  # the server is alive
    assert status == 200
    # the machine's own account is untouched (no faillock-like counting): PAM takes the right password
    from quadtank_tui.serve.auth import pam_authenticate

    assert pam_authenticate(bob.name, bob.password, "quadtank")
    # a burst refused unchecked counts no failures of bob's: the web login is not locked either
    status, cookie, headers = server.login(bob.name, bob.password)
    assert status == 303 and cookie
    assert sum(f"login-failed user={bob.name} " in line for line in server.audit_lines()) <= 5


def test_alices_tab_cannot_attach_to_or_stop_bobs_session(world: tuple[Serve, dict[str, User]],
                                                          bobs_run: subprocess.Popen[str]) -> None:
    server, users = world
    alice, bob = users["a"], users["b"]
    _, err = bobs_run.communicate(timeout=60)
    assert bobs_run.returncode == 0, err
    sid = f"{bob.name}-1"
    status, cookie, _ = server.login(alice.name, alice.password)
    assert status == 303 and cookie
    _, _, page = server.request("GET", "/", cookie=cookie)
    assert sid not in page  # her page offers her own sessions only

    async def tab(path: str) -> str:
        status, ws, session = await open_tab(server, cookie, path)
        assert status == 101 and ws is not None and session is not None
        text = await screen_text(ws, "\x00never", 30.0)  # until the tab closes
        await session.close()
        return text

    attach = asyncio.run(tab(f"/ws/attach/{sid}"))
    assert f"session {sid} belongs to {bob.name}" in attach and f"you are {alice.name}" in attach, attach
    # (a take-over, /ws/take_over/ID, meets the same refusal: the session decides, tests/session)
    assert server.request("GET", "/ws/stop/x", cookie=cookie, headers={"Origin": server.origin})[0] == 404
    # a tab runs the TUI, never `stop`: stopping bob's session would need his TUI, which refused her
    from quadtank_tui.session.runtime import list_sessions

    [info] = [i for i in list_sessions(server.runtime, prune=False) if i.id == sid]
    assert info.state == "Run" and info.owner == bob.name  # untouched
