"""What `quadtank serve` refuses to start with, the lab file's argon2 accounts, a
trusted reverse proxy's headers, and TLS (issue 44)."""

from __future__ import annotations

import http.client
import os
import shutil
import ssl
import subprocess
from pathlib import Path
from typing import Iterator

import pytest
from servekit import Serve, User, can_make_users, made_users, serving

from quadtank_tui.cli import main


@pytest.mark.parametrize("argv, words", [
    (["--host", "0.0.0.0"], "another address than the loopback needs TLS (--tls-cert and --tls-key) or a "
                            "reverse proxy (--trusted-proxy ADDRESS)"),
    (["--tls-cert", "c.pem"], "--tls-cert and --tls-key go together"),
    (["--port", "0"], "--port must be 1..65535"),
    (["--host", "rig7.example"], "--host must be an IP address of this machine"),
    (["--trusted-proxy", "proxy.lab"], "--trusted-proxy: must be the proxy's IP address"),
    (["--public-url", "https://rig7/x"], "--public-url: must be http(s)://HOST[:PORT] with nothing after"),
])
def test_refused_before_anything_listens(argv: list[str], words: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["serve", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("quadtank: error: ") and words in err and err.count("\n") == 1, err


def test_refused_without_the_labs_runtime_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """Every tab's user must meet the others' sessions, locks and bookings in one
    folder an administrator made: a link in its place is refused, not served."""
    import quadtank_tui.commands.serve as serve_command

    monkeypatch.setattr(serve_command, "has_switch_rights", lambda: True)
    monkeypatch.setattr(serve_command, "run", lambda *a: 0)  # were it accepted, nothing listens
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "rt").symlink_to(tmp_path / "elsewhere")
    monkeypatch.setenv("QUADTANK_RUNTIME", str(tmp_path / "rt"))
    monkeypatch.delenv("QUADTANK_LAB", raising=False)
    assert main(["serve", "--audit", str(tmp_path / "audit.log")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"quadtank: error: {tmp_path / 'rt'}: the runtime folder is not a folder") and \
        err.count("\n") == 1, err


pytestmark_users = pytest.mark.skipif(can_make_users() is not None, reason=str(can_make_users()))


@pytest.fixture(scope="module")
def lab_user() -> Iterator[tuple[Path, User]]:
    import tempfile

    from quadtank_tui.serve.auth import hash_password

    folder = Path(tempfile.mkdtemp(prefix="qtr-serve-lab-"))
    os.chmod(folder, 0o755)
    homes = folder / "homes"
    homes.mkdir()
    with made_users(homes, "lab") as users:
        user = users["lab"]
        lab = folder / "lab.yaml"
        lab.write_text(f"serve:\n  accounts:\n    {user.name}: '{hash_password('lab-only-password')}'\n"
                       "  trusted_proxy: 127.0.0.1\n  heartbeat_seconds: 1\n")
        os.chmod(lab, 0o644)
        yield lab, user
    shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture(scope="module")
def lab_server(lab_user: tuple[Path, User]) -> Iterator[tuple[Serve, User]]:
    """One plain-HTTP server of the lab file for the tests that only log in and open a tab."""
    lab, user = lab_user
    with serving(lab=lab) as server:
        yield server, user


@pytest.mark.wallclock
@pytestmark_users
def test_a_lab_file_account_and_a_trusted_proxys_headers(lab_server: tuple[Serve, User]) -> None:
    server, user = lab_server
    assert server.login(user.name, user.password)[0] == 401  # a lab account: its PAM password is not asked
    status, headers, _ = server.request(
        "POST", "/login", body=f"user={user.name}&password=lab-only-password",
        headers={"X-Forwarded-For": "198.51.100.9, 203.0.113.7", "X-Forwarded-Proto": "https"})
    assert status == 303 and "quadtank_session=" in headers["set-cookie"]
    assert "Secure" in headers["set-cookie"]  # https at the proxy
    lines = server.audit_lines()
    # the address the proxy added (the last), never one the browser wrote before it
    assert any(f"login user={user.name} address=203.0.113.7 via=lab" in line for line in lines), lines
    mode = server.audit.stat().st_mode & 0o777
    assert mode == 0o600  # no admin_group: root's only


@pytest.mark.wallclock
@pytestmark_users
@pytest.mark.skipif(shutil.which("openssl") is None, reason="needs openssl to make a test certificate")
def test_tls_gives_a_secure_cookie_and_a_wss_url(tmp_path: Path, lab_user: tuple[Path, User]) -> None:
    lab, user = lab_user
    cert, key = tmp_path / "c.pem", tmp_path / "k.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes", "-keyout", str(key), "-out",
                    str(cert), "-days", "1", "-subj", "/CN=127.0.0.1"], check=True, capture_output=True)
    with serving("--tls-cert", str(cert), "--tls-key", str(key), lab=lab) as server:
        context = ssl.create_default_context(cafile=str(cert))
        context.check_hostname = False

        def https(method: str, path: str, body: str | None = None, cookie: str | None = None
                  ) -> http.client.HTTPResponse:
            conn = http.client.HTTPSConnection("127.0.0.1", server.port, context=context, timeout=30)
            headers = {"Content-Type": "application/x-www-form-urlencoded"}
            if cookie:
                headers["Cookie"] = cookie
            conn.request(method, path, body=body, headers=headers)
            r = conn.getresponse()
            r.body = r.read()  # type: ignore[attr-defined]
            conn.close()
            return r

        r = https("POST", "/login", f"user={user.name}&password=lab-only-password")
        cookie = r.getheader("Set-Cookie") or ""
        assert r.status == 303 and "Secure" in cookie and "HttpOnly" in cookie and "SameSite=Strict" in cookie
        assert r.getheader("Strict-Transport-Security") == "max-age=31536000"
        page = https("GET", "/", cookie=cookie.split(";")[0])
        assert page.status == 200
        assert f'data-session-websocket-url="wss://127.0.0.1:{server.port}/ws"' in page.body.decode()  # type: ignore[attr-defined]
        plain = http.client.HTTPConnection("127.0.0.1", server.port, timeout=10)
        with pytest.raises((http.client.RemoteDisconnected, ConnectionError, http.client.BadStatusLine)):
            plain.request("GET", "/login")  # no plain HTTP on a TLS port
            plain.getresponse().read()


@pytest.mark.wallclock
@pytestmark_users
def test_a_tab_whose_network_is_lost_is_detached(lab_server: tuple[Serve, User]) -> None:
    """A browser that stops answering the websocket's pings (its network gone) is
    let go within 1.5 heartbeats (1 s here, 20 by default): detached, the session
    runs on."""
    import asyncio
    import time

    import aiohttp

    from quadtank_tui.session.runtime import list_sessions

    server, user = lab_server
    status, headers, _ = server.request("POST", "/login", body=f"user={user.name}&password=lab-only-password")
    cookie = headers["set-cookie"].split(";")[0]
    assert status == 303

    async def silent_tab() -> float:
        async with aiohttp.ClientSession() as session:
            ws = await session.ws_connect(f"ws://127.0.0.1:{server.port}/ws?width=100&height=30",
                                          headers={"Origin": server.origin, "Cookie": cookie}, autoping=False)
            seen = b""
            while b"you operate" not in seen:  # answer the pings until the screen is up
                msg = await ws.receive(timeout=40)
                if msg.type == aiohttp.WSMsgType.PING:
                    await ws.pong(msg.data)
                elif msg.type == aiohttp.WSMsgType.BINARY:
                    seen += msg.data
                else:
                    raise AssertionError(f"the tab closed before its screen: {msg}")
            silent = time.monotonic()  # from now on nothing is read, no pong is sent
            while time.monotonic() - silent < 20:
                await asyncio.sleep(0.2)
                if any(f" detach user={user.name}" in line for line in server.audit_lines()):
                    break
            return time.monotonic() - silent

    waited = asyncio.run(silent_tab())
    assert waited < 1 * 1.5 + 3.0 + 2.0, waited  # 1.5 heartbeats, the tab's quit grace, margin
    assert any(f"detach user={user.name}" in line for line in server.audit_lines())
    [info] = [i for i in list_sessions(server.runtime, prune=False) if i.uid == user.uid]
    assert info.clients == 0 and not info.ended  # detached, never stopped
