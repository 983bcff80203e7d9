"""Real users, a real `quadtank serve` and plain HTTP for tests/serve.

Users are made with useradd and chpasswd (root only), named with the test's pid,
each with a home of their own in a temporary folder, and removed afterwards.
Where this checkout's interpreter is out of other users' reach (a Python under
/root, mode 0700) each user is given search (x) on the folders that hide it, by an
ACL entry of their own (setfacl) removed with them: a lab installs quadtank where
its users may run it; the tests run it where it is.
"""

from __future__ import annotations

import contextlib
import http.client
import os
import shutil
import socket
import stat
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator, TypeVar

ROOT = Path(__file__).resolve().parents[2]


def can_make_users() -> str | None:
    """Why users cannot be made here (None: they can)."""
    if os.geteuid() != 0:
        return "needs root (useradd, chpasswd, and a server that starts tabs as other users)"
    for tool in ("useradd", "userdel", "chpasswd"):
        if shutil.which(tool) is None:
            return f"needs {tool}"
    return None


def hidden_folders() -> list[Path]:
    """The folders on the way to the interpreter, its stdlib and this checkout that
    other users may not search."""
    out: list[Path] = []
    for target in (Path(sys.executable).resolve(), Path(sys.base_prefix).resolve(), ROOT.resolve()):
        for folder in [*reversed(target.parents), target] if target.is_dir() else reversed(target.parents):
            try:
                mode = os.stat(folder).st_mode
            except OSError:
                continue
            if stat.S_ISDIR(mode) and not mode & stat.S_IXOTH and folder not in out:
                out.append(folder)
    return out


@dataclass(frozen=True)
class User:
    name: str
    password: str
    home: Path
    uid: int


@contextlib.contextmanager
def made_users(base: Path, *suffixes: str) -> Iterator[dict[str, User]]:
    """Users `qtr<pid><suffix>` with random passwords and homes under `base`."""
    import pwd
    import secrets

    made: list[str] = []
    acl: list[tuple[str, Path]] = []
    hidden = hidden_folders()
    if hidden and shutil.which("setfacl") is None:
        raise RuntimeError(f"{hidden[0]} hides the interpreter from other users and setfacl is missing "
                           "(apt-get install acl)")
    try:
        users: dict[str, User] = {}
        for suffix in suffixes:
            name = f"qtr{os.getpid()}{suffix}"
            home = base / name
            home.mkdir()
            subprocess.run(["useradd", "--no-create-home", "--home-dir", str(home), "--shell", "/bin/sh", name],
                           check=True, capture_output=True)
            made.append(name)
            password = "pw-" + secrets.token_urlsafe(12)
            subprocess.run(["chpasswd"], input=f"{name}:{password}\n", text=True, check=True, capture_output=True)
            entry = pwd.getpwnam(name)
            os.chown(home, entry.pw_uid, entry.pw_gid)
            for folder in hidden:
                subprocess.run(["setfacl", "-m", f"u:{name}:x", str(folder)], check=True, capture_output=True)
                acl.append((name, folder))
            users[suffix] = User(name, password, home, entry.pw_uid)
        yield users
    finally:
        for name, folder in acl:
            subprocess.run(["setfacl", "-x", f"u:{name}", str(folder)], capture_output=True)
        if made:
            end_processes_of(*made)  # all at once: each user's wait for their processes to go overlaps
        for name in made:
            for _ in range(20):  # a process reaped a moment late still counts for userdel
                if subprocess.run(["userdel", name], capture_output=True).returncode in (0, 6):
                    break
                time.sleep(0.1)


def end_processes_of(*users: str) -> None:
    """The processes the test made run as `users` (their sessions and guards), each by its pid."""
    import signal

    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:  # until none is left: userdel refuses a user with a live process
        listed = subprocess.run(["ps", "-o", "pid=", "-u", ",".join(users)], capture_output=True,
                                text=True).stdout.split()
        if not listed:
            return
        for pid in listed:
            with contextlib.suppress(ProcessLookupError, ValueError):
                os.kill(int(pid), signal.SIGKILL)
        time.sleep(0.05)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Serve:
    """`quadtank serve` in a process of its own, on a free port of 127.0.0.1."""

    def __init__(self, folder: Path, *extra: str, lab: Path | None = None) -> None:
        self.folder = folder
        self.runtime = folder / "rt"
        from quadtank_tui.session.folders import init_lab_folder

        init_lab_folder(self.runtime)  # the lab's runtime folder, as `quadtank lab init` makes it (issue 41)
        audit_dir = folder / "audit"
        audit_dir.mkdir(exist_ok=True)
        os.chmod(audit_dir, 0o750)
        self.audit = audit_dir / "audit.log"
        self.port = free_port()
        env = {k: v for k, v in os.environ.items() if k not in ("QUADTANK_LAB",)}
        env["QUADTANK_RUNTIME"] = str(self.runtime)
        env["PYTHONPATH"] = str(ROOT)
        argv = [sys.executable, "-m", "quadtank_tui", "serve", "--port", str(self.port), "--audit", str(self.audit),
                *extra]
        if lab is not None:
            argv += ["--lab", str(lab)]
        self.process = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                        cwd=folder)
        assert self.process.stdout is not None
        line = self.process.stdout.readline()
        if "listening" not in line:
            self.process.kill()
            raise RuntimeError(f"quadtank serve did not start: {line}{self.process.stderr.read() if self.process.stderr else ''}")
        self.origin = f"http://127.0.0.1:{self.port}"

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()

    def request(self, method: str, path: str, *, body: str | None = None, cookie: str | None = None,
                headers: dict[str, str] | None = None, timeout: float = 30.0) -> tuple[int, dict[str, str], str]:
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=timeout)
        h = dict(headers or {})
        if cookie:
            h["Cookie"] = f"quadtank_session={cookie}"
        if body is not None:
            h["Content-Type"] = "application/x-www-form-urlencoded"
        conn.request(method, path, body=body, headers=h)
        r = conn.getresponse()
        text = r.read().decode("utf-8", "replace")
        out = {k.lower(): v for k, v in r.getheaders()}
        out["set-cookie"] = "\n".join(v for k, v in r.getheaders() if k.lower() == "set-cookie")
        conn.close()
        return r.status, out, text

    def login(self, user: str, password: str) -> tuple[int, str | None, dict[str, str]]:
        from urllib.parse import urlencode

        status, headers, _ = self.request("POST", "/login", body=urlencode({"user": user, "password": password}))
        cookie = None
        for part in headers["set-cookie"].split(";"):
            part = part.strip()
            if part.startswith("quadtank_session="):
                cookie = part.split("=", 1)[1]
        return status, cookie, headers

    def audit_lines(self) -> list[str]:
        return self.audit.read_text().splitlines() if self.audit.exists() else []


@contextlib.contextmanager
def serving(*extra: str, lab: Path | None = None) -> Iterator[Serve]:
    folder = Path(tempfile.mkdtemp(prefix="qtr-serve-"))
    os.chmod(folder, 0o755)
    server = Serve(folder, *extra, lab=lab)
    try:
        yield server
    finally:
        server.stop()
        shutil.rmtree(folder, ignore_errors=True)


T = TypeVar("T")


def wait_for(predicate: Callable[[], T], timeout: float, step: float = 0.1) -> T:
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value or time.monotonic() > deadline:
            return value
        time.sleep(step)
