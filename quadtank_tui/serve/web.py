"""`quadtank serve`: the lab's TUI in a browser, behind a login, each tab its user's.

aiohttp speaks textual-serve's protocol with textual-serve's browser client
(textual.js, xterm.css); the server around it is ours, since textual-serve's has no
login, no Origin check and runs every tab as the server's user from a shell with
the server's environment.  The server holds no rig and runs no loop: each tab is
`quadtank` as the tab's user (serve/tab.py), a client of that user's session like
an SSH login.

Every request passes `guard`: a Host that is not this server's is refused (421:
DNS rebinding), then everything but the login page needs a live login cookie
(401, or a redirect to /login for a page).  The websocket is refused (403) when its
Origin is not the server's own.  Security headers on every answer: a strict
Content-Security-Policy (everything from 'self'), no framing, no referrer, no cache.
"""

from __future__ import annotations

import asyncio
import ipaddress
import socket
import ssl
from dataclasses import dataclass, field
from importlib.resources import files
from pathlib import Path
from typing import Awaitable, Callable
from urllib.parse import quote, urlsplit

from aiohttp import WSMsgType, web

from quadtank_tui.serve.audit import AuditLog
from quadtank_tui.serve.auth import FAIL_DELAY, Account, Authenticator, Throttle
from quadtank_tui.serve.web_config import ServeSettings
from quadtank_tui.serve.pages import app_page, login_page
from quadtank_tui.serve.tab import Tab, TabUser
from quadtank_tui.serve.websessions import COOKIE, LoginStore, WebLogin
from quadtank_tui.session.runtime import valid_id

#: Open tabs per login, and per user, at most.
MAX_TABS_PER_LOGIN = 8
MAX_TABS_PER_USER = 16
#: Largest message a browser may send on the websocket (keys, a resize).
MAX_WS_MESSAGE = 64 << 10
#: How often a tab checks that its login is still live (logout, expiry end it).
LOGIN_CHECK = 5.0
MODES = ("attach", "observe", "take_over")
WEB_DRIVER_FPS = 30


@dataclass
class ServeOptions:
    host: str = "127.0.0.1"
    port: int = 8000
    tls: ssl.SSLContext | None = None
    settings: ServeSettings = field(default_factory=ServeSettings)
    #: what every tab gets of the server's environment (the lab's files)
    passed_env: dict[str, str] = field(default_factory=dict)
    runtime: Path | None = None
    audit: AuditLog | None = None
    #: bound to another address without TLS: only the trusted proxy may connect
    proxy_only: bool = False
    #: for the tests: the authenticator's argon2/PAM checker
    authenticator: Authenticator | None = None


def static_folder() -> Path:
    """textual-serve's browser client: textual.js, xterm.css, fonts."""
    return Path(str(files("textual_serve") / "static"))


def own_hosts(host: str) -> set[str]:
    """The names and addresses a browser may use for this server (its Host header)."""
    names = {host}
    try:
        addr = ipaddress.ip_address(host)
    except ValueError:
        addr = None
    if addr is not None and addr.is_loopback:
        names |= {"127.0.0.1", "localhost", "[::1]", "::1"}
    elif addr is not None and addr.is_unspecified:
        names |= {"127.0.0.1", "localhost", socket.gethostname(), socket.getfqdn()}
        try:
            names |= {str(info[4][0]) for info in socket.getaddrinfo(socket.gethostname(), None)}
        except OSError:
            pass
    if addr is not None and addr.version == 6:
        names.add(f"[{host}]")
    return names


class Server:
    def __init__(self, options: ServeOptions) -> None:
        self.o = options
        s = options.settings
        self.auth = options.authenticator or Authenticator(lab_accounts=s.accounts, use_pam=s.pam,
                                                           pam_service=s.pam_service)
        self.throttle = Throttle()
        self.logins = LoginStore(idle=s.idle_minutes * 60.0, maximum=s.max_hours * 3600.0)
        self.hosts = own_hosts(options.host)
        if s.public_url:
            self.hosts.add(urlsplit(s.public_url).hostname or "")
        self._checking = InFlight()
        self.tabs: dict[int, tuple[WebLogin, web.WebSocketResponse]] = {}
        self._tab_ids = 0

    # --- who and where -----------------------------------------------------------------------

    def peer(self, request: web.Request) -> str:
        return request.transport.get_extra_info("peername")[0] if request.transport else "?"

    def from_proxy(self, request: web.Request) -> bool:
        proxy = self.o.settings.trusted_proxy
        return proxy is not None and self.peer(request) == proxy

    def address(self, request: web.Request) -> str:
        """The browser's address: the proxy's X-Forwarded-For (its last entry, the one
        the proxy added) only from the trusted proxy; else the connection's peer."""
        if self.from_proxy(request):
            forwarded = request.headers.get("X-Forwarded-For", "")
            last = forwarded.split(",")[-1].strip()
            try:
                return str(ipaddress.ip_address(last))
            except ValueError:
                pass
        return self.peer(request)

    def scheme(self, request: web.Request) -> str:
        if self.o.tls is not None:
            return "https"
        if self.from_proxy(request) and request.headers.get("X-Forwarded-Proto") == "https":
            return "https"
        return "http"

    def own_origin(self, request: web.Request) -> str:
        if self.o.settings.public_url:
            return self.o.settings.public_url
        return f"{self.scheme(request)}://{request.host}"

    def host_ok(self, request: web.Request) -> bool:
        host = request.host
        name = host.rsplit(":", 1)[0] if not host.endswith("]") else host
        if host.startswith("[") and "]:" in host:
            name = host.split("]:")[0] + "]"
        return name in self.hosts

    def login_of(self, request: web.Request) -> WebLogin | None:
        return self.logins.find(request.cookies.get(COOKIE))

    def audit(self, event: str, **fields: object) -> None:
        if self.o.audit is not None:
            self.o.audit.write(event, **fields)

    # --- the application -----------------------------------------------------------------------

    def app(self) -> web.Application:
        app = web.Application(middlewares=[self.guard], client_max_size=16 << 10)
        app.add_routes([
            web.get("/login", self.login_form),
            web.post("/login", self.login),
            web.get("/logout", self.logout),
            web.post("/logout", self.logout),
            web.get("/", self.index),
            web.get("/ws", self.websocket),
            web.get("/ws/{mode}/{session}", self.websocket),
            web.static("/static", static_folder(), show_index=False, follow_symlinks=False),
        ])
        app.on_shutdown.append(self._close_tabs)
        return app

    @web.middleware
    async def guard(self, request: web.Request,
                    handler: Callable[[web.Request], Awaitable[web.StreamResponse]]) -> web.StreamResponse:
        if not self.host_ok(request):
            return self._headers(web.Response(status=421, text="this server does not answer for that host\n"))
        if self.o.proxy_only and not self.from_proxy(request):
            return self._headers(web.Response(status=403, text="this server is reached through its proxy\n"))
        if request.path != "/login":
            login = self.login_of(request)
            if login is None:
                if request.method == "GET" and request.path == "/" or request.path == "/logout":
                    return self._headers(redirect("/login"))
                return self._headers(web.Response(status=401, text="log in first: /login\n"))
            request["login"] = login
        try:
            response = await handler(request)
        except web.HTTPException as exc:
            response = exc
        return self._headers(response)

    def _headers(self, response: web.StreamResponse) -> web.StreamResponse:
        h = response.headers
        h.setdefault("Content-Security-Policy", "default-src 'self'; connect-src 'self' ws: wss:; "
                     "style-src 'self' 'unsafe-inline'; script-src 'self' 'unsafe-inline'; "
                     "frame-ancestors 'none'; form-action 'self'; base-uri 'none'")
        h.setdefault("X-Frame-Options", "DENY")
        h.setdefault("X-Content-Type-Options", "nosniff")
        h.setdefault("Referrer-Policy", "same-origin")  # no-referrer makes Chromium send Origin: null
        h.setdefault("Cache-Control", "no-store")
        if self.o.tls is not None:
            h.setdefault("Strict-Transport-Security", "max-age=31536000")
        return response

    def _origin_ok(self, request: web.Request, *, required: bool) -> bool:
        origin = request.headers.get("Origin")
        if origin is None:
            return not required
        return origin == self.own_origin(request)

    # --- login and logout ----------------------------------------------------------------------

    async def login_form(self, request: web.Request) -> web.StreamResponse:
        if self.login_of(request) is not None:
            return redirect("/")
        return web.Response(text=login_page(), content_type="text/html")

    async def login(self, request: web.Request) -> web.StreamResponse:
        if not self._origin_ok(request, required=False):
            return web.Response(status=403, text="a login from another site's page is refused\n")
        try:
            form = await request.post()
        except (ValueError, web.HTTPException):
            return web.Response(status=400, text="the login form is a user and a password\n")
        user, password = form.get("user"), form.get("password")
        if not isinstance(user, str) or not isinstance(password, str):
            return web.Response(status=400, text="the login form is a user and a password\n")
        address = self.address(request)
        keys = (f"user:{user[:64]}", f"addr:{address}")
        wait = self.throttle.wait(keys)
        if wait > 0:
            self.audit("login-slowed", user=user, address=address, wait=f"{wait:.0f}s")
            return web.Response(status=429, headers={"Retry-After": str(int(wait) + 1)},
                                text=login_page(f"Too many failed logins: try again in {int(wait) + 1} s.", user),
                                content_type="text/html")
        if not self._checking.enter(keys):
            self.audit("login-slowed", user=user, address=address, why="another check in progress")
            return web.Response(status=429, headers={"Retry-After": "2"},
                                text=login_page("A login for this name or from here is being checked: try again.",
                                                user), content_type="text/html")
        started = asyncio.get_running_loop().time()
        try:
            account = await self.auth.check(user, password)
        finally:
            self._checking.leave(keys)
        if account is None:
            self.throttle.failed(keys)
            self.audit("login-failed", user=user, address=address,
                       failures=self.throttle.failures(keys[0]))
            spent = asyncio.get_running_loop().time() - started
            await asyncio.sleep(max(FAIL_DELAY - spent, 0.0))
            return web.Response(status=401, text=login_page("Wrong user name or password.", user),
                                content_type="text/html")
        if account.uid == 0:
            self.audit("login-refused", user=user, address=address, why="root")
            return web.Response(status=403, text=login_page("root may not use the lab from a browser."),
                                content_type="text/html")
        self.throttle.succeeded(keys)
        token = self.logins.open(account, address)
        self.audit("login", user=account.name, address=address, via=account.via)
        response = redirect("/")
        response.set_cookie(COOKIE, token, httponly=True, samesite="Strict", path="/",
                            secure=self.scheme(request) == "https")
        return response

    async def logout(self, request: web.Request) -> web.StreamResponse:
        if request.method == "POST" and not self._origin_ok(request, required=False):
            return web.Response(status=403, text="a logout from another site's page is refused\n")
        login = self.logins.close(request.cookies.get(COOKIE))
        if login is not None:
            self.audit("logout", user=login.account.name, address=self.address(request))
            for tab_id in list(login.tabs):
                _, ws = self.tabs.get(tab_id, (None, None))
                if ws is not None:
                    await ws.close(code=4001, message=b"logged out")
        response = redirect("/login")
        response.del_cookie(COOKIE, path="/", samesite="Strict", httponly=True)
        return response

    # --- the app's page and its websocket ---------------------------------------------------------

    def _mode(self, query: dict[str, str]) -> tuple[str, str | None]:
        for mode in MODES:
            sid = query.get(mode)
            if sid is not None:
                if not valid_id(sid):  # never an option of `attach` (--take-over), a path or a line's end
                    raise web.HTTPBadRequest(text="a session id is a user's name, '-' and a number "
                                             "(letters, digits, '.', '_' and '-')\n")
                return mode, sid
        return "attach", None

    async def index(self, request: web.Request) -> web.StreamResponse:
        login: WebLogin = request["login"]
        mode, sid = self._mode(dict(request.query))
        ws_scheme = "wss" if self.own_origin(request).startswith("https") else "ws"
        netloc = urlsplit(self.own_origin(request)).netloc
        # textual.js adds ?width=..&height=..: what the tab runs is in the path
        url = f"{ws_scheme}://{netloc}/ws" + (f"/{mode}/{quote(sid)}" if sid else "")
        what = {"attach": "your session", "observe": f"watching {sid}",
                "take_over": f"taking {sid} over"}[mode] if sid else "your session (a new one if none runs)"
        own = [(i.id, f"/?attach={i.id}") for i in self._sessions_of(login.account)]
        return web.Response(text=app_page(user=login.account.name, websocket_url=url, what=what, sessions=own),
                            content_type="text/html")

    def _sessions_of(self, account: Account) -> list:
        if self.o.runtime is None:
            return []
        from quadtank_tui.session.runtime import list_sessions

        try:
            return [i for i in list_sessions(self.o.runtime, prune=False) if i.uid == account.uid]
        except OSError:
            return []

    def _running(self) -> dict[str, str]:
        if self.o.runtime is None:
            return {}
        from quadtank_tui.session.runtime import list_sessions

        try:
            return {i.id: i.owner for i in list_sessions(self.o.runtime, prune=False)}
        except OSError:
            return {}

    async def websocket(self, request: web.Request) -> web.StreamResponse:
        login: WebLogin = request["login"]
        if not self._origin_ok(request, required=True):
            self.audit("websocket-refused", user=login.account.name, address=self.address(request),
                       origin=request.headers.get("Origin", "none"))
            return web.Response(status=403, text="this page's Origin is not this server's\n")
        account = login.account
        if len(login.tabs) >= MAX_TABS_PER_LOGIN or \
                sum(1 for lg, _ in self.tabs.values() if lg.account.uid == account.uid) >= MAX_TABS_PER_USER:
            return web.Response(status=429, text="too many open tabs\n")
        if "mode" in request.match_info:
            mode, sid = self._mode({request.match_info["mode"]: request.match_info["session"]})
            if mode != request.match_info["mode"]:
                return web.Response(status=404, text="no such tab\n")
        else:
            mode, sid = "attach", None
        width = _bounded(request.query.get("width"), 80, 20, 500)
        height = _bounded(request.query.get("height"), 24, 8, 200)
        # pings every heartbeat_seconds (20); no pong within half of it closes the tab
        # (detached): a browser whose network is lost is let go in under a minute
        ws = web.WebSocketResponse(heartbeat=self.o.settings.heartbeat_seconds, max_msg_size=MAX_WS_MESSAGE)
        await ws.prepare(request)
        self._tab_ids += 1
        tab_id = self._tab_ids
        login.tabs.add(tab_id)
        self.tabs[tab_id] = (login, ws)
        args = {"attach": ["attach", sid] if sid else [], "observe": ["attach", "--observe", sid or ""],
                "take_over": ["attach", "--take-over", sid or ""]}[mode]
        before = self._running()
        address = self.address(request)
        self.audit({"attach": "attach", "observe": "observe", "take_over": "take-over"}[mode],
                   user=account.name, address=address, session=sid or "own")
        groups = tuple(sorted(set(_groups(account))))
        tab = Tab(TabUser(account.name, account.uid, account.gid, groups, account.home), args,
                  width=width, height=height, to_browser=ws.send_bytes, passed_env=self.o.passed_env)
        try:
            await tab.start()
            await self._relay(ws, tab, login)
        finally:
            status = await tab.close()
            if not tab.started.is_set() and tab.stderr_tail and not ws.closed:
                # refused before its screen started (not yours, no such session): say why
                text = tab.stderr_tail.decode("utf-8", "replace").replace("\n", "\r\n")
                await ws.send_bytes(("\x1b[0m\r\n" + text).encode())
                await asyncio.sleep(0.2)
            login.tabs.discard(tab_id)
            self.tabs.pop(tab_id, None)
            if not ws.closed:
                await ws.close()
            self.audit("detach", user=account.name, address=address, status=status)
            after = self._ended(before)
            for ended_id, why in after.items():
                if why == f"stopped by {account.name}":
                    self.audit("stop", user=account.name, session=ended_id)
        return ws

    def _ended(self, before: dict[str, str]) -> dict[str, str]:
        if self.o.runtime is None or not before:
            return {}
        from quadtank_tui.session.runtime import ended_sessions

        try:
            return {i.id: i.ended for i in ended_sessions(self.o.runtime) if i.id in before}
        except OSError:
            return {}

    async def _relay(self, ws: web.WebSocketResponse, tab: Tab, login: WebLogin) -> None:
        """Browser -> tab until either side ends; the login checked every LOGIN_CHECK s."""
        ended = asyncio.create_task(tab.wait_reader())

        async def watch_login() -> None:
            while self.logins.live(login):
                await asyncio.sleep(LOGIN_CHECK)

        watch = asyncio.create_task(watch_login())
        incoming = asyncio.create_task(self._from_browser(ws, tab, login))
        try:
            await asyncio.wait({ended, watch, incoming}, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for task in (ended, watch, incoming):
                task.cancel()

    async def _from_browser(self, ws: web.WebSocketResponse, tab: Tab, login: WebLogin) -> None:
        import json

        async for message in ws:
            if message.type != WSMsgType.TEXT:
                continue
            try:
                envelope = json.loads(message.data)
            except ValueError:
                return
            if not isinstance(envelope, list) or not envelope or not isinstance(envelope[0], str):
                return
            kind = envelope[0]
            self.logins.touch(login)
            if kind == "stdin" and len(envelope) > 1 and isinstance(envelope[1], str):
                await tab.keys(envelope[1])
            elif kind == "resize" and len(envelope) > 1 and isinstance(envelope[1], dict):
                size = envelope[1]
                await tab.resize(_bounded(size.get("width"), 80, 20, 500), _bounded(size.get("height"), 24, 8, 200))
            elif kind == "ping" and len(envelope) > 1:
                await ws.send_json(["pong", envelope[1]])
            elif kind in ("focus", "blur"):
                await tab.meta({"type": kind})

    async def _close_tabs(self, app: web.Application) -> None:
        for _, ws in list(self.tabs.values()):
            await ws.close(code=1001, message=b"server stopping")


class InFlight:
    """Password checks under way per key: one per user name, PER_ADDRESS per address
    (a classroom behind one address logs in side by side); a burst of guesses is
    refused while one of them is checked, instead of queueing for PAM."""

    PER_ADDRESS = 4

    def __init__(self) -> None:
        self._count: dict[str, int] = {}

    def enter(self, keys: tuple[str, ...]) -> bool:
        for key in keys:
            limit = self.PER_ADDRESS if key.startswith("addr:") else 1
            if self._count.get(key, 0) >= limit:
                return False
        for key in keys:
            self._count[key] = self._count.get(key, 0) + 1
        return True

    def leave(self, keys: tuple[str, ...]) -> None:
        for key in keys:
            left = self._count.get(key, 0) - 1
            if left > 0:
                self._count[key] = left
            else:
                self._count.pop(key, None)


def redirect(location: str) -> web.Response:
    """303 See Other to `location` (after a POST, the browser GETs it)."""
    return web.Response(status=303, headers={"Location": location})


def _groups(account: Account) -> list[int]:
    import os

    try:
        return os.getgrouplist(account.name, account.gid)
    except OSError:
        return [account.gid]


def _bounded(value: object, default: int, low: int, high: int) -> int:
    try:
        number = int(str(value))
    except ValueError:
        return default
    return min(max(number, low), high)
