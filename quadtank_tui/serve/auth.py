"""Who may log in: the machine's accounts through PAM, and the lab file's accounts
with argon2 hashes; failed logins slowed down per user name and per address.

A login is answered the same way whether the name exists or not: the same page,
the same status, and a lab account's name unknown to the lab file still costs an
argon2 verification (of a hash made at start), so the time says nothing either.
The slowing is ours and in memory (never PAM's faillock-like counting, which
would lock the student's SSH too): after `FREE_FAILURES` failures in `WINDOW`
seconds for a name or an address, the next attempt on it waits
2^(n - FREE_FAILURES) s (at most `MAX_WAIT`) since the last failure and is refused
without a look at its password until then.  Every failed attempt is answered
after at least `FAIL_DELAY` s.
"""

from __future__ import annotations

import asyncio
import pwd
import time
from collections import OrderedDict, deque
from dataclasses import dataclass
from typing import Callable, Mapping

#: Failures for a name or an address allowed in WINDOW before attempts wait.
FREE_FAILURES = 3
#: Seconds over which failures count.
WINDOW = 900.0
#: The longest wait between attempts on one name or address (seconds).
MAX_WAIT = 60.0
#: A failed login is answered after at least this long (seconds).
FAIL_DELAY = 1.0
#: Names and addresses remembered at most (the oldest forgotten first): bounded memory.
MAX_KEYS = 20000
#: PAM checks running at once (each blocks a thread, PAM's own delay included).
PAM_THREADS = 4
#: Longest user name and password accepted (bytes of UTF-8): bounded work.
MAX_NAME = 64
MAX_PASSWORD = 1024


class Throttle:
    """Failures counted per key ('user:NAME', 'addr:IP'); `wait(keys)` is how long
    the caller must still wait before an attempt is looked at (0: now)."""

    def __init__(self, *, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._failures: OrderedDict[str, deque[float]] = OrderedDict()

    def _recent(self, key: str) -> deque[float]:
        times = self._failures.get(key)
        if times is None:
            return deque()
        cutoff = self._clock() - WINDOW
        while times and times[0] < cutoff:
            times.popleft()
        return times

    def wait(self, keys: tuple[str, ...]) -> float:
        """Seconds until an attempt on `keys` may be checked.

        >>> t = Throttle(clock=lambda: 100.0)
        >>> for _ in range(5): t.failed(("user:bob",))
        >>> t.wait(("user:bob",)), t.wait(("user:alice",))
        (4.0, 0.0)
        """
        now = self._clock()
        longest = 0.0
        for key in keys:
            times = self._recent(key)
            over = len(times) - FREE_FAILURES
            if over > 0:
                longest = max(longest, min(2.0 ** (over - 1) * 2.0, MAX_WAIT) - (now - times[-1]))
        return max(longest, 0.0)

    def failed(self, keys: tuple[str, ...]) -> None:
        now = self._clock()
        for key in keys:
            times = self._failures.pop(key, None) or deque(maxlen=64)
            times.append(now)
            self._failures[key] = times
        while len(self._failures) > MAX_KEYS:
            self._failures.popitem(last=False)

    def failures(self, key: str) -> int:
        return len(self._recent(key))

    def succeeded(self, keys: tuple[str, ...]) -> None:
        for key in keys:
            self._failures.pop(key, None)


@dataclass(frozen=True)
class Account:
    """A login that passed: the OS account its tabs run as, and how it was checked."""

    name: str
    uid: int
    gid: int
    home: str
    via: str  # "pam" or "lab"


class Authenticator:
    """Checks a name and password: the lab file's argon2 accounts first (`lab_accounts`:
    name -> hash; each name must be an account of this machine, which its tabs run
    as), then PAM (service `pam_service`) when `use_pam`."""

    def __init__(self, *, lab_accounts: Mapping[str, str], use_pam: bool, pam_service: str) -> None:
        from argon2 import PasswordHasher

        self._hasher = PasswordHasher()
        self._lab = dict(lab_accounts)
        self._dummy = self._hasher.hash("not a password of anyone's")
        self.use_pam = use_pam
        self.pam_service = pam_service
        self._pam_slots = asyncio.Semaphore(PAM_THREADS)

    async def check(self, name: str, password: str) -> Account | None:
        """The account when `password` is `name`'s, else None (the same for a name
        that does not exist)."""
        if not _fair(name, password):
            await asyncio.to_thread(self._lab_verify, self._dummy, password[:MAX_PASSWORD])
            return None
        entry = _account(name)
        if name in self._lab:
            ok = await asyncio.to_thread(self._lab_verify, self._lab[name], password)
            return Account(name, entry.pw_uid, entry.pw_gid, entry.pw_dir, "lab") if ok and entry else None
        if self.use_pam:
            async with self._pam_slots:
                ok = await asyncio.to_thread(pam_authenticate, name, password, self.pam_service)
            return Account(name, entry.pw_uid, entry.pw_gid, entry.pw_dir, "pam") if ok and entry else None
        await asyncio.to_thread(self._lab_verify, self._dummy, password)
        return None

    def _lab_verify(self, hashed: str, password: str) -> bool:
        from argon2.exceptions import Argon2Error, InvalidHashError

        try:
            return bool(self._hasher.verify(hashed, password))
        except (Argon2Error, InvalidHashError, ValueError):
            return False


def hash_password(password: str) -> str:
    """An argon2id hash for the lab file's `serve: accounts:` (argon2-cffi's defaults)."""
    from argon2 import PasswordHasher

    return PasswordHasher().hash(password)


def _fair(name: str, password: str) -> bool:
    """A name and password worth checking: bounded, printable, no NUL (PAM's C strings)."""
    return (0 < len(name.encode()) <= MAX_NAME and len(password.encode()) <= MAX_PASSWORD and bool(password)
            and name.isprintable() and "\0" not in password and not name.startswith("-")
            and ":" not in name and "/" not in name)


def _account(name: str) -> pwd.struct_passwd | None:
    try:
        return pwd.getpwnam(name)
    except KeyError:
        return None


def pam_authenticate(name: str, password: str, service: str) -> bool:
    """PAM's verdict on `name`'s `password` (authentication, then the account's
    validity: expired or locked accounts are refused), through python-pam."""
    import pam

    checker = pam.PamAuthenticator()
    try:
        return bool(checker.authenticate(name, password, service=service, call_end=True, resetcreds=False))
    except Exception:  # a broken PAM stack refuses; it never lets in
        return False
