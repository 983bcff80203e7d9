"""Connection churn against a running session (issue 41, item 9): another user loops
connect / send `{bad\\n` / close as fast as it can while a Simul session and an
Active session (the virtual rig, `quadtank rig`) sample in real time.

For each session: the sampling slots skipped and |jitter| p50 / p99 / max of the
samples taken while the churn lasted (the session's own figures: its summary
line for the skipped slots and the whole run's p99 / max, and the jitter of every
sample it published to an observer attached before the churn, for the window's
p50 / p99 / max), the size of the session's output file (`.out`), whether the
DAQ guard said anything there, and the connections the attacker made.

Run as root it makes a user of its own (useradd, removed at the end) and attacks
from children forked and dropped to that user's ids, so the session sees another
user through SO_PEERCRED; otherwise the attacker is the owner itself.

    .venv/bin/python benchmarks/socket_churn.py [--seconds 30] [--attackers 1] [--only simul,active]
    PYTHONPATH=/work/main .venv/bin/python benchmarks/socket_churn.py   # another tree's code

Figures are printed, not asserted (the machine may be shared).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from socket_campaign import Attacker, _other_user  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PARAMS = ROOT / "params"
#: The line the issue's attacker sent on each connection.
BAD = b"{bad\n"


def churn(path: str, seconds: float) -> Any:
    """Connect, send BAD, close, for `seconds`; how many connections were made."""
    def attack() -> Any:
        made = failed = 0
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            sock.settimeout(1.0)
            try:
                sock.connect(path)
                sock.send(BAD)
                made += 1
            except OSError:
                failed += 1
            sock.close()
        return {"connections": made, "failed": failed}
    return attack


def burn(seconds: float) -> Any:
    """The control: a process that only spins for `seconds` (the CPU an attacker takes, without a connection)."""
    def attack() -> Any:
        end = time.monotonic() + seconds
        n = 0
        while time.monotonic() < end:
            n += 1
        return {"connections": 0, "failed": 0}
    return attack


def _owner_attaches(path: str) -> float:
    """Seconds this process (the session's owner) took to attach as an observer (inf: refused)."""
    from quadtank_tui.session.client import SessionClient, SessionError

    t0 = time.monotonic()
    try:
        with SessionClient(path, role="observer", timeout=10.0):
            return time.monotonic() - t0
    except (SessionError, OSError):
        return float("inf")


def _detached(args: list[str], env: dict[str, str]) -> tuple[str, Path, subprocess.CompletedProcess[str]]:
    """`quadtank run ... --detach`: the session's socket and output file."""
    out = subprocess.run([sys.executable, "-m", "quadtank_tui", "run", "--detach", *args],
                         capture_output=True, text=True, env=env, timeout=60, cwd=env["QUADTANK_RUNTIME"])
    m = re.search(r"session (\S+) runs", out.stdout)
    o = re.search(r"summary goes to (\S+\.out)", out.stdout)
    if out.returncode != 0 or m is None or o is None:
        raise RuntimeError(f"run --detach failed: {out.stdout}{out.stderr}")
    sid, dot_out = m.group(1), Path(o.group(1))
    sock = next(p for p in dot_out.parent.rglob(f"{sid}.sock"))
    return str(sock), dot_out, out


def _summary(text: str) -> dict[str, float]:
    m = re.search(r"ran \S+ s: (\d+) samples, (\d+) overruns(?: \((\d+) sampling slots skipped\))?, "
                  r"\|jitter\| p99 ([0-9.]+) ms, max ([0-9.]+) ms", text)
    if m is None:
        return {}
    return {"samples": int(m.group(1)), "overruns": int(m.group(2)), "skipped": int(m.group(3) or 0),
            "p99_ms": float(m.group(4)), "max_ms": float(m.group(5))}


def _jitter_window(path: str) -> tuple[Any, list[tuple[float, float]]]:
    """Attach an observer (thread) collecting every published sample's jitter."""
    from quadtank_tui.session.client import SessionClient

    got: list[tuple[float, float]] = []
    stop = threading.Event()

    def watch() -> None:
        with SessionClient(path, role="observer", timeout=10.0) as client:
            last = -1
            while not stop.is_set():
                snap = client.snapshot()
                if snap is not None and snap.stats.samples != last:
                    last = snap.stats.samples
                    got.append((time.monotonic(), abs(snap.stats.jitter_last)))
                time.sleep(0.002)
    t = threading.Thread(target=watch, daemon=True)
    t.start()
    return (t, stop), got


def one(kind: str, seconds: float, attackers: int, user: tuple[int, int] | None, work: Path,
        control: bool = False) -> dict[str, Any]:
    runtime = work / f"rt-{kind}"
    runtime.mkdir()
    runtime.chmod(0o1777)
    env = {**os.environ, "QUADTANK_RUNTIME": str(runtime), "PYTHONPATH": os.environ.get("PYTHONPATH", str(ROOT))}
    rig = None
    args = ["--realtime", "--duration", f"{seconds + 6:g}", "--log", str(work / f"{kind}.log")]
    if kind == "active":
        rig = subprocess.Popen([sys.executable, "-m", "quadtank_tui", "rig", "--port", "0", "--map",
                                str(PARAMS / "virtual-rig.yaml")], stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True, env=env, cwd=work)
        assert rig.stdout is not None
        line = rig.stdout.readline()
        port = int(line.split("serving on ")[1].split()[0].rsplit(":", 1)[1])
        threading.Thread(target=rig.stdout.read, daemon=True).start()
        cfg = work / "rig.yaml"
        cfg.write_text((PARAMS / "virtual-rig.yaml").read_text().replace("port: 5020", f"port: {port}"))
        args += ["--daq", str(cfg)]
    try:
        sock, dot_out, _ = _detached(args, env)
        started = time.monotonic()
        (watcher, stop), jit = _jitter_window(sock)
        time.sleep(3.0)
        t0 = time.monotonic()
        attach: list[float] = []
        gangs = [Attacker(user, burn(seconds) if control else churn(sock, seconds)) for _ in range(attackers)]
        timer = threading.Timer(seconds / 2, lambda: attach.append(_owner_attaches(sock)))
        timer.start()
        made = failed = 0
        for a in gangs:
            r = a.result(seconds + 60)
            if "error" in r:
                print(f"    attacker: {r['error']}", flush=True)
            made += r.get("connections", 0)
            failed += r.get("failed", 0)
            a.done()
        if not gangs:
            time.sleep(seconds)
        t1 = time.monotonic()
        timer.join()
        time.sleep(1.0)
        stop.set()
        watcher.join(5)
        inside = np.array([j for t, j in jit if t0 <= t <= t1] or [0.0])
        outside = [(j, t - started) for t, j in jit if not t0 <= t <= t1] or [(0.0, 0.0)]
        worst_out = max(outside)
        end = time.monotonic() + seconds + 30
        text = ""
        while time.monotonic() < end:
            text = dot_out.read_text(errors="replace") if dot_out.exists() else ""
            if " stopped" in text or "ended" in text:
                break
            time.sleep(0.2)
        time.sleep(0.5)
        text = dot_out.read_text(errors="replace")
        return {"kind": kind, **_summary(text), "window_p50_ms": 1000 * float(np.percentile(inside, 50)),
                "window_p99_ms": 1000 * float(np.percentile(inside, 99)), "window_max_ms": 1000 * float(inside.max()),
                "window_samples": len(inside), "outside_max_ms": 1000 * worst_out[0], "outside_at": worst_out[1], "out_bytes": dot_out.stat().st_size,
                "out_lines": text.count("\n"), "guard": text.count("quadtank guard:"),
                "attach_s": attach[0] if attach else float("nan"), "connections": made, "failed": failed, "tail": text[-600:]}
    finally:
        if rig is not None:
            rig.send_signal(signal.SIGTERM)
            try:
                rig.wait(10)
            except subprocess.TimeoutExpired:
                rig.kill()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--attackers", type=int, default=1, help="attacking processes at once")
    ap.add_argument("--only", default="simul,active")
    ap.add_argument("--control", action="store_true",
                    help="the attackers only spin, without connecting (what the CPU they take costs alone)")
    ap.add_argument("--verbose", action="store_true", help="print the end of each .out")
    a = ap.parse_args(argv)
    other = _other_user()
    user = other[1] if other else None
    print(f"churn {a.seconds:g} s, {a.attackers} attacker(s) as "
          + (f"user {other[0]}" if other else "the owner itself (not root: no other user)"), flush=True)
    work = Path(tempfile.mkdtemp(prefix="qchurn-"))
    work.chmod(0o755)
    try:
        for kind in a.only.split(","):
            r = one(kind, a.seconds, a.attackers, user, work, a.control)
            print(f"  {kind:6s}: {r.get('skipped', '?')} slots skipped of {r.get('samples', '?')} samples; |jitter| "
                  f"window p50 {r['window_p50_ms']:.3f} ms, p99 {r['window_p99_ms']:.3f} ms, max "
                  f"{r['window_max_ms']:.3f} ms ({r['window_samples']} samples seen; outside the churn max "
                  f"{r['outside_max_ms']:.3f} ms, {r['outside_at']:.1f} s after the start); whole run p99 "
                  f"{r.get('p99_ms', '?')} ms, max {r.get('max_ms', '?')} ms; .out {r['out_bytes']} B "
                  f"({r['out_lines']} lines), guard lines {r['guard']}; {r['connections']} connections "
                  f"({r['failed']} failed); the owner attached in {r['attach_s']:.2f} s", flush=True)
            if a.verbose:
                print("    " + r["tail"].replace("\n", "\n    "), flush=True)
    finally:
        if other:
            subprocess.run(["userdel", other[0]], capture_output=True)
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
