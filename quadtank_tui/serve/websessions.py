"""The browser's login sessions: a random cookie per login, held by the server only.

The cookie is 32 random bytes (secrets.token_urlsafe); the server keeps the
SHA-256 of it, with who logged in, from where and when.  It ends when idle for
`idle` seconds, at `maximum` seconds after the login whatever happens, and at
logout: a copy of the cookie taken before (a stolen one) is then worth nothing.
A restart of the server ends every login.
"""

from __future__ import annotations

import hashlib
import secrets
import time
from dataclasses import dataclass, field
from typing import Callable

from quadtank_tui.serve.auth import Account

COOKIE = "quadtank_session"
#: Logins held at once, at most (the oldest end first): bounded memory.
MAX_LOGINS = 10000


@dataclass
class WebLogin:
    """One login: its account, the address it came from, when it started and was last used."""

    account: Account
    address: str
    started: float
    last_seen: float
    tabs: set[int] = field(default_factory=set)


def _digest(token: str) -> str:
    return hashlib.sha256(token.encode("utf-8", "replace")).hexdigest()


class LoginStore:
    def __init__(self, *, idle: float, maximum: float, clock: Callable[[], float] = time.monotonic) -> None:
        self.idle, self.maximum = idle, maximum
        self._clock = clock
        self._logins: dict[str, WebLogin] = {}

    def open(self, account: Account, address: str) -> str:
        """A new login; its cookie value."""
        token = secrets.token_urlsafe(32)
        now = self._clock()
        self._logins[_digest(token)] = WebLogin(account, address, now, now)
        while len(self._logins) > MAX_LOGINS:
            self._logins.pop(next(iter(self._logins)))
        return token

    def find(self, token: str | None, *, touch: bool = True) -> WebLogin | None:
        """The login of cookie `token` if it is live (touching it: idle time from now)."""
        if not token or len(token) > 128:
            return None
        key = _digest(token)
        login = self._logins.get(key)
        if login is None:
            return None
        now = self._clock()
        if now - login.last_seen > self.idle or now - login.started > self.maximum:
            del self._logins[key]
            return None
        if touch:
            login.last_seen = now
        return login

    def live(self, login: WebLogin) -> bool:
        """Whether `login` still counts (not ended, not expired); a tab's keys keep it in use."""
        now = self._clock()
        return any(v is login for v in self._logins.values()) and now - login.started <= self.maximum

    def close(self, token: str | None) -> WebLogin | None:
        """Logout: the login ended; the login it was (None: no such live login)."""
        if not token:
            return None
        return self._logins.pop(_digest(token), None)

    def touch(self, login: WebLogin) -> None:
        login.last_seen = self._clock()
