"""The socket campaign of benchmarks/hardening.py (issue 24): another user against a
running session process - malformed lines, a flood of idle connections, lines of
a megabyte without an end - each round judged on the session (still running), its
host's RSS and CPU, and whether its owner can attach.

Run as root it makes a user of its own (useradd, removed at the end) and attacks
from children forked and dropped to that user's ids, so the session sees another
user through SO_PEERCRED; otherwise the attacker is the owner itself (then the
owner's own per-user limit applies and "owner can attach" is not judged).

    .venv/bin/python benchmarks/hardening.py --only sockets
    PYTHONPATH=/work/main .venv/bin/python benchmarks/hardening.py --only sockets   # another tree's code
"""

from __future__ import annotations

import json
import os
import random
import resource
import select
import shutil
import signal
import socket
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

#: The issue's figures: 1,017 idle connections, 900 connections of 1 MB each.
IDLE, LONG = 1017, 900
LINE = 1 << 20


@dataclass
class Worst:
    rss_mb: float = 0.0
    cpu: float = 0.0
    attach_s: float = 0.0
    refused_owner: int = 0
    notes: list[str] = field(default_factory=list)

    def line(self, rss0: float) -> str:
        return (f"    worst: host RSS {rss0:.0f} -> {self.rss_mb:.0f} MB, CPU {100 * self.cpu:.0f} % of a core, "
                f"owner attached in {self.attach_s:.2f} s at worst, refused {self.refused_owner} times")


def malformed_lines(rng: random.Random, n: int) -> list[bytes]:
    """Lines that are not messages: the issue's two, deep nesting, bad types in
    good tags, mutated good lines, random bytes."""
    good = [b'{"@":"Hello","role":"observer","client":"x","take_over":false}',
            b'{"@":"Submit","id":1,"command":{"@":"SetState","state":"Run"}}',
            b'{"@":"StopSession"}']
    fixed = [b'{"@":"map","v":[[[1],2]]}', b"[" * 200_000, b"{" * 5000, b'{"@":"tuple","v":' + b"[" * 900,
             b'{"@":"Hello","role":{"@":"map","v":[[[],1]]}}', b'{"@":"enum","t":"Role","v":[]}',
             b'{"@":"array","shape":[99999999999,99999999999],"b64":""}', b'{"@":"complex","v":["a","b"]}',
             b'{"@":"path","v":{"@":"map","v":[]}}', b"9" * 100_000, b'"\\ud800"', b"\xff\xfe\x00"]
    out = list(fixed)
    while len(out) < n:
        base = bytearray(rng.choice(good))
        for _ in range(rng.randint(1, 4)):
            i = rng.randrange(len(base))
            choice = rng.random()
            if choice < 0.4:
                base[i] = rng.randrange(256)
            elif choice < 0.7:
                base[i:i] = rng.choice([b"[", b"{", b'{"@":"map","v":[[[1],2]]}', b'{"@":"tuple","v":[]}', b"\n"])
            else:
                del base[i:i + rng.randint(1, 5)]
        out.append(bytes(base))
    return out[:n]


def _connect(path: str, timeout: float) -> socket.socket | None:
    sock = socket.socket(socket.AF_UNIX)
    sock.settimeout(timeout)
    try:
        sock.connect(path)
    except OSError:
        sock.close()
        return None
    return sock


class Attacker:
    """`attack()` in a child forked as `user` (uid, gid; None: this user); its result
    comes back as JSON; it keeps what it opened until `done()`."""

    def __init__(self, user: tuple[int, int] | None, attack: Callable[[], Any]) -> None:
        out_r, out_w = os.pipe()
        keep_r, keep_w = os.pipe()
        pid = os.fork()
        if pid == 0:
            code = 0
            try:
                for fd in map(int, os.listdir("/proc/self/fd")):
                    if fd > 2 and fd not in (out_w, keep_r):
                        try:
                            os.close(fd)
                        except OSError:
                            pass
                if user is not None:
                    os.setgroups([])
                    os.setgid(user[1])
                    os.setuid(user[0])
                os.write(out_w, json.dumps(attack()).encode())
                os.close(out_w)
                os.read(keep_r, 1)
            except BaseException as exc:  # noqa: BLE001 - reported as the result
                os.write(out_w, json.dumps({"error": repr(exc)}).encode())
                code = 1
            os._exit(code)
        os.close(out_w)
        os.close(keep_r)
        self.pid, self._out, self._keep = pid, out_r, keep_w

    def result(self, timeout: float = 600.0) -> Any:
        data = b""
        end = time.monotonic() + timeout
        while time.monotonic() < end and select.select([self._out], [], [], end - time.monotonic())[0]:
            chunk = os.read(self._out, 1 << 16)
            if not chunk:
                break
            data += chunk
        return json.loads(data) if data else {"error": "no answer"}

    def done(self) -> None:
        for fd in (self._keep, self._out):
            os.close(fd)
        try:
            os.kill(self.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        os.waitpid(self.pid, 0)


def _send_each(path: str, lines: list[bytes]) -> Callable[[], Any]:
    def attack() -> Any:
        dropped = 0
        for line in lines:
            sock = _connect(path, 5.0)
            if sock is None:
                continue
            try:
                sock.sendall(line + b"\n")
                dropped += sock.recv(1 << 16) == b""
            except OSError:
                dropped += 1
            sock.close()
        return {"sent": len(lines), "dropped": dropped}
    return attack


def _hold(path: str, n: int, payload: bytes) -> Callable[[], Any]:
    def attack() -> Any:
        held: list[socket.socket] = []
        end = time.monotonic() + 8.0  # a full backlog: try again while the session takes them in
        while len(held) < n and time.monotonic() < end:
            sock = _connect(path, 0.5)
            if sock is None:
                time.sleep(0.005)
                continue
            try:
                if payload:
                    sock.sendall(payload)
                held.append(sock)
            except OSError:
                sock.close()
        globals()["_kept"] = held
        time.sleep(0.5)
        # Still held: not hung up on nor told Refused by the session.
        alive = [sock for sock in held if not select.select([sock], [], [], 0)[0]]
        return {"asked": n, "connected": len(held), "held": len(alive)}
    return attack


def _rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return 0.0


def _cpu(pid: int, seconds: float = 1.0) -> float:
    def ticks() -> int:
        f = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return int(f[11]) + int(f[12])

    t0, c0 = time.monotonic(), ticks()
    time.sleep(seconds)
    return (ticks() - c0) / os.sysconf("SC_CLK_TCK") / (time.monotonic() - t0)


def _owner_attaches(path: str) -> float | None:
    """Seconds the owner took to attach and have a command applied; None: refused."""
    from quadtank_tui.engine.commands import SetState
    from quadtank_tui.session.client import SessionClient, SessionError

    t0 = time.monotonic()
    try:
        with SessionClient(path, timeout=10.0) as owner:
            if not owner.submit(SetState("Run")).result(30).ok:
                return None
    except (SessionError, OSError):
        return None
    return time.monotonic() - t0


def _other_user() -> tuple[str, tuple[int, int]] | None:
    if os.geteuid() != 0 or shutil.which("useradd") is None:
        return None
    name = f"qhs{os.getpid() % 100000}"
    subprocess.run(["useradd", "-M", "-N", "-s", "/usr/sbin/nologin", name], check=True, capture_output=True)
    ids = subprocess.run(["id", "-u", name], capture_output=True, text=True).stdout, \
        subprocess.run(["id", "-g", name], capture_output=True, text=True).stdout
    return name, (int(ids[0]), int(ids[1]))


def campaign_sockets(t: Any, n: int, rng: random.Random, work: Path) -> None:
    """`t` is hardening.Tally: ran, accepted (rounds the session came through), failures."""
    from quadtank_tui.engine.runner import engine_spec
    from quadtank_tui.session.launch import SessionSpec, start_session
    from quadtank_tui.files.proc import pid_alive
    from quadtank_tui.session.runtime import list_sessions

    runtime = Path(tempfile.mkdtemp(prefix="qhs-run-"))
    runtime.chmod(0o1777)
    other = _other_user()
    user = other[1] if other else None
    spec = engine_spec(clock="virtual", speed=1.0, params_dir=work / "params", logs_dir=work / "logs")
    worst = Worst()
    session: list[Any] = []

    def live() -> Any:
        """The session under attack; a new one if the last ended (so every round runs)."""
        if not session or not pid_alive(session[-1].pid):
            session.append(start_session(SessionSpec(spec, str(runtime))))
            # The descriptors of a default Linux login (the host was at 1024), whatever this shell has.
            hard = resource.prlimit(session[-1].pid, resource.RLIMIT_NOFILE)[1]
            resource.prlimit(session[-1].pid, resource.RLIMIT_NOFILE, (min(1024, hard), hard))
            print(f"    session {session[-1].id} (pid {session[-1].pid}), RSS {_rss_mb(session[-1].pid):.0f} MB; "
                  "attacker: " + (f"user {other[0]}" if other else "the owner itself (not root: no other user)"),
                  flush=True)
        return session[-1]

    def judge(what: str, info: Any, data: bytes | None = None) -> None:
        t.ran += 1
        time.sleep(0.2)
        if not (pid_alive(info.pid) and any(i.id == info.id for i in list_sessions(runtime))):
            t.fail("session ended", f"{what}: the session ended", data)
            return
        worst.rss_mb = max(worst.rss_mb, _rss_mb(info.pid))
        # The host's CPU while the owner tries to attach (a connection waiting to be
        # accepted: what made a host out of descriptors spin).
        attempt: list[float | None] = []
        trying = threading.Thread(target=lambda: attempt.append(_owner_attaches(info.socket)))
        trying.start()
        cpu = _cpu(info.pid)
        worst.cpu = max(worst.cpu, cpu)
        trying.join()
        took = attempt[0]
        if took is None:
            worst.refused_owner += 1
            if other:
                t.fail("owner refused", f"{what}: the owner could not attach")
                return
        else:
            worst.attach_s = max(worst.attach_s, took)
        if cpu > 0.5:
            t.fail("cpu", f"{what}: the host used {100 * cpu:.0f} % of a core")
            return
        if worst.rss_mb - rss0 > 100:
            t.fail("memory", f"{what}: the host's RSS went {rss0:.0f} -> {worst.rss_mb:.0f} MB")
            return
        t.accepted += 1

    rss0 = _rss_mb(live().pid)
    try:
        lines = malformed_lines(rng, n)
        for k in range(0, len(lines), 25):
            batch = lines[k:k + 25]
            info = live()
            a = Attacker(user, _send_each(info.socket, batch))
            a.result()
            a.done()
            judge(f"malformed lines {k + 1}..{k + len(batch)}", info, b"\n".join(batch))
        for what, count, payload in (("idle connections", IDLE, b""),
                                     ("1 MB lines without a newline", LONG, b"x" * LINE)):
            info = live()
            a = Attacker(user, _hold(info.socket, count, payload))
            got = a.result()
            judge(f"{count} {what} ({got})", info)
            worst.notes.append(f"{what}: {got}")
            a.done()
    finally:
        for info in session:
            if pid_alive(info.pid):
                os.kill(info.pid, signal.SIGTERM)
        if other:
            time.sleep(0.5)
            subprocess.run(["userdel", other[0]], capture_output=True)
        shutil.rmtree(runtime, ignore_errors=True)
    print(worst.line(rss0), flush=True)
    for note in worst.notes:
        print(f"    {note}", flush=True)
