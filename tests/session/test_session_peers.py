"""A real session process against other users and against running out of file
descriptors (issue 24): another user's malformed lines, floods of connections and
lines without an end cost that user's connections only; the session runs on, its
memory stays put, and its owner gets in.

Other users are real (useradd, when run as root; skipped otherwise): each attacks
from a child forked from this process that drops to that user's ids, so the session
learns who it is from the kernel (SO_PEERCRED) as it does in a lab.
"""

from __future__ import annotations

import json
import os
import pwd
import resource
import shutil
import signal
import socket
import sys
import time
from pathlib import Path
from typing import Any, Callable, Iterator

import pytest
from otherusers import made_users

from quadtank_tui.engine import commands as c
from quadtank_tui.engine.runner import engine_spec
from quadtank_tui.session.client import SessionClient, stop_session_at
from quadtank_tui.session.info import SessionInfo
from quadtank_tui.session.launch import SessionSpec, start_session
from quadtank_tui.session.runtime import list_sessions
from quadtank_tui.session.server import MAX_PER_USER

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc, SO_PEERCRED, prlimit")

MALFORMED = [b'{"@":"map","v":[[[1],2]]}', b"[" * 200_000, b'{"@":"Hello","role":"admin"}', b"\xff" * 50]


def _session(tmp_path: Path, runtime: Path) -> SessionInfo:
    spec = engine_spec(clock="virtual", speed=1.0, params_dir=tmp_path / "params", logs_dir=tmp_path / "logs")
    return start_session(SessionSpec(spec, str(runtime)))


@pytest.fixture
def runtime() -> Iterator[Path]:
    """A runtime folder every user can reach, as a lab's (pytest's tmp_path is its user's alone)."""
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="qts-run-"))
    folder.chmod(0o1777)
    yield folder
    for _ in range(100):  # a session that just said it stopped still writes its ended record
        shutil.rmtree(folder, ignore_errors=True)
        if not folder.exists():
            break
        time.sleep(0.05)


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise AssertionError("no VmRSS")


def _cpu_share(pid: int, seconds: float = 1.0) -> float:
    """The share of one core the process used over `seconds` of wall time."""
    t0, c0 = time.monotonic(), _cpu_seconds(pid)
    time.sleep(seconds)
    return (_cpu_seconds(pid) - c0) / (time.monotonic() - t0)


def _connect(path: str, timeout: float = 0.2) -> socket.socket | None:
    """A connection, or None when the session's backlog is full (or it is gone)."""
    sock = socket.socket(socket.AF_UNIX)
    sock.settimeout(timeout)
    if sock.connect_ex(path) == 0:
        return sock
    sock.close()
    return None


# --- other users ------------------------------------------------------------------------------


@pytest.fixture
def two_users() -> Iterator[list[tuple[int, int]]]:
    """Two real users (uid, gid), made for the test and removed after it (otherusers.py)."""
    if os.geteuid() != 0 or shutil.which("useradd") is None:
        pytest.skip("needs root and useradd to make real users")
    with made_users(*(f"qts{os.getpid() % 100000}{x}" for x in "bc")) as names:
        yield [(pwd.getpwnam(n).pw_uid, pwd.getpwnam(n).pw_gid) for n in names]


class AsUser:
    """`attack()` run by a child forked from this process as another user; its JSON
    result is read with `result()`; it holds its connections until `release()`."""

    def __init__(self, user: tuple[int, int], attack: Callable[[], Any]) -> None:
        res_r, res_w = os.pipe()
        self._hold_r, self._hold_w = os.pipe()
        self.pid = os.fork()
        if self.pid == 0:  # the child: no pytest, no threads of ours; only sockets, then _exit
            status = 0
            try:
                for fd in map(int, os.listdir("/proc/self/fd")):  # an earlier child's pipe ends too
                    if fd > 2 and fd not in (res_w, self._hold_r):
                        try:
                            os.close(fd)
                        except OSError:
                            pass
                os.setgroups([])
                os.setgid(user[1])
                os.setuid(user[0])
                os.write(res_w, json.dumps(attack()).encode() + b"\n")
                os.read(self._hold_r, 1)  # hold the connections until released
            except BaseException as exc:  # noqa: BLE001 - said through the result pipe
                os.write(res_w, json.dumps({"failed": repr(exc)}).encode() + b"\n")
                status = 1
            os._exit(status)
        os.close(res_w)
        os.close(self._hold_r)
        self._res = res_r

    def result(self, timeout: float = 60.0) -> Any:
        import select

        assert select.select([self._res], [], [], timeout)[0], "the other user's child did not answer"
        data = os.read(self._res, 1 << 20)
        assert data, "the other user's child failed"
        result = json.loads(data)
        assert "failed" not in result, result
        return result

    def release(self) -> int:
        """Let it go; its exit status."""
        os.close(self._hold_w)
        os.close(self._res)
        self._hold_w = -1
        return os.waitstatus_to_exitcode(os.waitpid(self.pid, 0)[1])

    def end(self) -> None:
        """After a failure: end the child (by its pid) so its user can be removed."""
        if self._hold_w >= 0:
            os.kill(self.pid, signal.SIGKILL)
            os.waitpid(self.pid, 0)
            self._hold_w = -1


def _malformed_and_long_lines(path: str) -> Callable[[], Any]:
    def attack() -> Any:
        hung_up = 0
        for line in MALFORMED:  # each on a connection of its own, before any Hello
            sock = _connect(path, 5.0)
            assert sock is not None
            try:
                sock.sendall(line + b"\n")
                hung_up += sock.recv(1 << 16) == b"" or True
            except OSError:
                hung_up += 1
            sock.close()
        held, refused = [], 0
        for _ in range(40):  # 1 MB each, no newline
            sock = _connect(path, 2.0)
            if sock is None:
                refused += 1
                continue
            try:
                sock.sendall(b"x" * (1 << 20))
                held.append(sock)
            except OSError:
                refused += 1
                sock.close()
        return {"hung_up": hung_up, "held": len(held), "refused": refused}

    return attack


def _idle_flood(path: str, n: int = 60) -> Callable[[], Any]:
    def attack() -> Any:
        held, told = [], 0
        for _ in range(n):
            sock = _connect(path, 2.0)
            if sock is None:
                continue
            sock.settimeout(0.05)
            try:
                said = sock.recv(1000)
                told += b"Refused" in said
                sock.close()
                continue
            except socket.timeout:
                held.append(sock)  # let in, waiting for its Hello
            except OSError:
                sock.close()
        globals()["_held"] = held
        return {"held": len(held), "told": told}

    return attack


def test_another_users_malformed_lines_and_floods_cost_that_user_only(
        tmp_path: Path, runtime: Path, two_users: list[tuple[int, int]]) -> None:
    info = _session(tmp_path, runtime)
    children: list[AsUser] = []
    try:
        rss0 = _rss_mb(info.pid)
        long_lines = AsUser(two_users[0], _malformed_and_long_lines(info.socket))
        children.append(long_lines)
        flood = AsUser(two_users[1], _idle_flood(info.socket))
        children.append(flood)
        lines, idle = long_lines.result(), flood.result()
        rss = _rss_mb(info.pid)
        print(f"session RSS {rss0:.0f} -> {rss:.0f} MB; 1 MB lines: {lines}; idle flood: {idle}")
        # The session runs on; the other users got no more than their share, told why.
        assert [i.id for i in list_sessions(runtime)] == [info.id]
        assert lines["hung_up"] == len(MALFORMED)
        assert idle["held"] == MAX_PER_USER and idle["told"] >= 60 - MAX_PER_USER - 5
        assert rss - rss0 < 20, f"the session's memory grew by {rss - rss0:.0f} MB"
        # The owner gets in and drives it while the flood is held.
        with SessionClient(info.socket) as owner:
            assert owner.submit(c.SetState("Run")).result(30).ok
            assert owner.role == "operator"
        assert [child.release() for child in children] == [0, 0]
    finally:
        for child in children:
            child.end()
        stop_session_at(info.socket)


def test_out_of_descriptors_accept_backs_off_and_the_owner_gets_back_in(tmp_path: Path, runtime: Path,
                                                                       poll: Callable[..., bool]) -> None:
    """The session at its descriptor limit (prlimit 48) under a flood of an
    administrator's connections (no per-user limit): accept fails with EMFILE. It
    used to spin on it (87 % of a core; 31 % on a loaded test machine); it pauses
    (0-1 %), and once the flood is gone the owner attaches."""
    info = _session(tmp_path, runtime)
    flood: list[socket.socket] = []
    try:
        resource.prlimit(info.pid, resource.RLIMIT_NOFILE, (48, 48))
        end = time.monotonic() + 3.0  # past the limit, the rest wait in the listen backlog until it is full
        while len(flood) < 100 and time.monotonic() < end:
            sock = _connect(info.socket)
            if sock is None:
                time.sleep(0.01)  # the backlog is full for now: the session takes them in its time
            else:
                flood.append(sock)
        # Its accept may be pausing (up to a second) after an EMFILE that a file it
        # had open for a moment caused: it takes the waiting ones in once it resumes.
        assert poll(lambda: len(os.listdir(f"/proc/{info.pid}/fd")) >= 47, 10.0), \
            f"the session was never at its limit ({len(os.listdir(f'/proc/{info.pid}/fd'))} descriptors)"
        share = _cpu_share(info.pid)
        print(f"{len(flood)} connections at the limit: the session used {100 * share:.0f} % of a core")
        assert share < 0.1, f"the session spun at {100 * share:.0f} % of a core"
        for sock in flood:
            sock.close()
        flood.clear()
        with SessionClient(info.socket) as owner:
            assert owner.submit(c.SetState("Run")).result(30).ok
    finally:
        for sock in flood:
            sock.close()
        try:
            stop_session_at(info.socket)
        except OSError:
            os.kill(info.pid, signal.SIGTERM)
