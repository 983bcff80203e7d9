"""Issue 41's attacks on the shared runtime folder (items 1-8), by two real users
against each other and against root, on a checkout of the program: each attack's
answer, one line each, so the same script shows them before and after a change.

    sudo .venv/bin/python benchmarks/runtime_attacks.py [--code CHECKOUT]

Needs root (useradd; the users are removed after).  --code: the checkout whose
package runs (default: this one); an older one is driven through the same
commands (`quadtank run --detach`, `sessions`, `stop`, the lock's acquire).  The
runtime folder is made as that checkout's installation says: by `quadtank lab
init` where the command exists, else by the first program (the old way).  Every
command runs under a 2 GB address space and a 20 s timeout (rc 124: hung)."""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(HERE / "tests" / "serve"))

from servekit import made_users  # noqa: E402  (users the interpreter is reachable by)

LIMIT = 2 << 30
TIMEOUT = 20.0

HOLD = """
import sys, time
from quadtank_tui.session.lab import load_lab_config
from quadtank_tui.session.lock import DaqLock
lock = DaqLock.acquire("127.0.0.1:15041/1", load_lab_config())
print("held", lock.path, flush=True)
for line in sys.stdin:
    print(lock.lost() or "ours", flush=True)
"""

FAKE_ENDED = """
import os, socket, sys
s = socket.socket(socket.AF_UNIX)
s.bind(sys.argv[1]); os.chmod(sys.argv[1], 0o666); s.listen(8)
print("listening", flush=True)
while True:
    c, _ = s.accept()
    c.sendall(b'{"@": "Ended", "reason": "stopped by root"}\\n')
    c.close()
"""


class Lab:
    def __init__(self, code: Path, top: Path, users: dict) -> None:
        self.code, self.top = code, top
        self.alice, self.bob = users["a"], users["b"]
        self.rt = top / "rt"
        self.new = (code / "quadtank_tui" / "session" / "folders.py").exists()
        self.procs: list[subprocess.Popen[str]] = []

    def env(self, rt: Path | None = None, **more: str) -> dict[str, str]:
        return {"PATH": os.environ["PATH"], "PYTHONPATH": str(self.code), "QUADTANK_RUNTIME": str(rt or self.rt),
                "NO_COLOR": "1", "HOME": str(self.top), "PYTHONDONTWRITEBYTECODE": "1", **more}

    def argv(self, user: object | None, *args: str) -> list[str]:
        pre = [] if user is None else ["runuser", "-u", user.name, "--"]  # type: ignore[attr-defined]
        return [*pre, "prlimit", f"--as={LIMIT}", sys.executable, *args]

    def run(self, user: object | None, *args: str, rt: Path | None = None, **env: str) -> tuple[int, str, str]:
        try:
            p = subprocess.run(self.argv(user, *args), capture_output=True, text=True, timeout=TIMEOUT,
                               cwd=self.cwd(user), env=self.env(rt, **env), start_new_session=True)
            return p.returncode, p.stdout, p.stderr
        except subprocess.TimeoutExpired as exc:
            return 124, (exc.stdout or b"").decode() if isinstance(exc.stdout, bytes) else exc.stdout or "", "hung"

    def q(self, user: object | None, *args: str, **kw: object) -> tuple[int, str, str]:
        return self.run(user, "-m", "quadtank_tui", *args, **kw)  # type: ignore[arg-type]

    def py(self, user: object | None, code: str, *args: str, **kw: object) -> tuple[int, str, str]:
        return self.run(user, "-c", textwrap.dedent(code), *args, **kw)  # type: ignore[arg-type]

    def start(self, user: object, code: str, *args: str, rt: Path | None = None) -> subprocess.Popen[str]:
        p = subprocess.Popen(self.argv(user, "-c", textwrap.dedent(code), *args), stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=self.cwd(user),
                             env=self.env(rt))
        self.procs.append(p)
        return p

    def cwd(self, user: object | None) -> Path:
        return self.top if user is None else user.home  # type: ignore[attr-defined]

    def place(self, user: object) -> Path:
        """Where the user's records are: the runtime folder (old) or their folder in it (new)."""
        return self.rt / "users" / str(user.uid) if self.new else self.rt  # type: ignore[attr-defined]

    def as_alice(self, code: str, *args: str) -> str:
        rc, out, err = self.py(self.alice, code, *args)
        return (out + err).strip().splitlines()[-1] if (out + err).strip() else f"rc {rc}"

    def detach(self, user: object, seconds: int = 300) -> tuple[int, str, str]:
        return self.q(user, "run", "--duration", str(seconds), "--speed", "1", "--log",
                      str(user.home / "run.log"), "--detach")  # type: ignore[attr-defined]


def plant(lab: Lab, name: str, text: str) -> str:
    """alice writes `name` where the old layout put records, else in her own folder."""
    code = """
        import os, sys
        for folder in sys.argv[3:]:
            try:
                if not os.path.isdir(folder):
                    os.makedirs(folder); os.chmod(folder, 0o755)
                with open(os.path.join(folder, sys.argv[1]), "w") as f:
                    f.write(sys.argv[2])
                print("planted in", folder); break
            except OSError as exc:
                print("refused:", folder, exc.strerror)
    """
    return lab.as_alice(code, name, text, str(lab.rt), str(lab.rt / "users" / str(lab.alice.uid)))


def record(lab: Lab, **fields: object) -> str:
    base = {"id": "x", "owner": lab.bob.name, "uid": lab.bob.uid, "pid": 999999, "started": "2026-12-01T10:00:00",
            "plant": "quadtank", "operation": "Active", "state": "Run", "socket": "", "cwd": "/"}
    return json.dumps({**base, **fields})


def bob_session(lab: Lab) -> dict:
    rc, out, err = lab.q(lab.bob, "sessions", "--json")
    running = [s for s in json.loads(out or "[]") if not s.get("ended") and s["owner"] == lab.bob.name]
    return running[0] if running else {}


def alive(pid: int) -> bool:
    """Whether `pid` runs (a zombie does not: nothing reaps a detached session here)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except (OSError, IndexError):
        return False


def attacks(lab: Lab) -> list[tuple[str, str]]:
    out: list[tuple[str, str]] = []
    say = lambda item, answer: out.append((item, answer.replace("\n", " | ")[:300]))  # noqa: E731
    if lab.new:
        rc, o, e = lab.q(None, "lab", "init", str(lab.rt))
        say("setup", f"quadtank lab init: rc {rc}")
    rc, o, e = lab.detach(lab.bob)
    say("setup", f"bob's run --detach: rc {rc} {e.strip()[-120:]}")
    bob1 = bob_session(lab)
    if not bob1:
        say("setup", "bob's session is not listed: stop")
        return out
    sid, pid = bob1["id"], bob1["pid"]
    sock = Path(lab.place(lab.bob)) / f"{sid}.sock"
    # 1. a copy of bob's record, pid 999999; and one saying bob's id is ended long ago
    say("1 plant a copy (pid 999999)", plant(lab, f"{lab.alice.name}-forged-a.json", record(lab, id=sid)))
    rc, o, e = lab.q(lab.bob, "sessions")
    say("1 bob's `sessions` after", f"rc {rc}; {sid} listed running: {sid in o.split('ended')[0]}; "
        f"{sid}.sock there: {sock.exists()}")
    say("1 plant `id: <bob's>, ended 2020`",
        plant(lab, f"{lab.alice.name}-x.json", record(lab, id=sid, ended="stopped", ended_at="2020-01-01T00:00:00")))
    rc, o, e = lab.q(None, "sessions")
    files = sorted(p.name for p in Path(lab.place(lab.bob)).glob(f"{sid}.*"))
    say("1 root's `sessions` after", f"rc {rc}; bob's files left: {files}; bob's process alive: {alive(pid)}")
    # 3. path traversal as root
    victim = lab.top / "victim"
    victim.mkdir()
    for name in ("b.sock", "b.json", "b.out", "a.json"):
        (victim / name).write_text("root's\n")
    plant(lab, f"{lab.alice.name}-t1.json", record(lab, id="../victim/b", owner=lab.alice.name, uid=lab.alice.uid,
                                                   ended="x", ended_at="2020-01-01T00:00:00"))
    plant(lab, f"{lab.alice.name}-t2.json", record(lab, id="/.." * 12 + str(victim / "a"), owner=lab.alice.name,
                                                   uid=lab.alice.uid))
    rc, o, e = lab.q(None, "sessions")
    left = sorted(p.name for p in victim.iterdir())
    kept = all(p.read_text() == "root's\n" for p in victim.iterdir())
    say("3 root's `sessions` with ids ../victim/b, /../../victim/a", f"rc {rc}; victim files {left}, "
        f"all unchanged: {kept}")
    # 8. terminal escapes in an owner field, of a live process of alice's
    sleeper = lab.start(lab.alice, "import time; time.sleep(600)")
    time.sleep(0.3)
    esc = "alice\x1b]0;PWNED\x07\x1b[2J"
    n = 900000 + os.getpid() % 1000
    plant(lab, f"{lab.alice.name}-{n}.json", record(lab, id=f"{lab.alice.name}-{n}", owner=esc, uid=lab.alice.uid,
                                                    pid=sleeper.pid))
    rc, o, e = lab.q(None, "sessions")
    say("8 root's `sessions` with an owner field of escapes", f"rc {rc}; raw ESC in output: {chr(27) in o}; "
        f"escaped shown: {'x1b]0;PWNED' in o}")
    # 4. a FIFO; 5. a link to /dev/zero
    lab.as_alice("import os, sys\nfor f in sys.argv[1:]:\n    try: os.mkfifo(f); print('fifo', f); break\n"
                 "    except OSError as e: print('refused', f, e.strerror)",
                 str(lab.rt / "fifo.json"), str(lab.rt / "users" / str(lab.alice.uid) / "fifo.json"))
    t = time.monotonic()
    rc, o, e = lab.q(None, "sessions")
    say("4 root's `sessions` with a FIFO", f"rc {rc} in {time.monotonic() - t:.1f} s")
    rc, o, e = lab.q(None, "stop", sid + "-none")
    say("4 root's `stop` with a FIFO", f"rc {rc}: {(o + e).strip()[-100:]}")
    t = time.monotonic()
    rc, o, e = lab.detach(lab.bob, 60)
    say("4 bob's `run --detach` with a FIFO", f"rc {rc} in {time.monotonic() - t:.1f} s: {e.strip()[-100:]}")
    lab.as_alice("import os, sys\nfor f in sys.argv[1:]:\n    try: os.unlink(f)\n    except OSError: pass",
                 str(lab.rt / "fifo.json"), str(lab.rt / "users" / str(lab.alice.uid) / "fifo.json"))
    lab.as_alice("import os, sys\nfor f in sys.argv[1:]:\n    try: os.symlink('/dev/zero', f); print('ok'); break\n"
                 "    except OSError as e: print('refused', f, e.strerror)",
                 str(lab.rt / "zero.json"), str(lab.rt / "users" / str(lab.alice.uid) / "zero.json"))
    t = time.monotonic()
    rc, o, e = lab.q(None, "sessions")
    say("5 root's `sessions` with zero.json -> /dev/zero (2 GB limit)",
        f"rc {rc} in {time.monotonic() - t:.1f} s: {(e.strip().splitlines() or [''])[-1][:100]}")
    lab.as_alice("import os, sys\nfor f in sys.argv[1:]:\n    try: os.unlink(f)\n    except OSError: pass",
                 str(lab.rt / "zero.json"), str(lab.rt / "users" / str(lab.alice.uid) / "zero.json"))
    # 2. a faked stop: a record of alice's naming her listener, which answers Ended
    fake_path = Path(lab.place(lab.alice)) / "fake.sock"
    lab.as_alice("import os, sys\nif not os.path.isdir(sys.argv[1]):\n os.makedirs(sys.argv[1]); "
                 "os.chmod(sys.argv[1], 0o755)", str(fake_path.parent))
    fake = lab.start(lab.alice, FAKE_ENDED, str(fake_path))
    assert fake.stdout is not None
    fake.stdout.readline()
    plant(lab, f"{lab.alice.name}-a.json", record(lab, id=sid, pid=fake.pid, socket=str(fake_path)))
    rc, o, e = lab.q(None, "stop", sid)
    time.sleep(0.5)
    say("2 root's `stop <bob's>` with alice's record and Ended-answering socket",
        f"rc {rc}: {(o + e).strip()[:110]}; bob's process alive after: {alive(pid)}")
    # 6. a student-owned locks/: alice makes a fresh runtime folder's locks/ first, bob holds, alice removes
    fresh = lab.top / "fresh"
    lab.as_alice("import os, sys; os.makedirs(sys.argv[1] + '/locks'); os.chmod(sys.argv[1], 0o1777); "
                 "os.chmod(sys.argv[1] + '/locks', 0o1777)", str(fresh))
    holder = lab.start(lab.bob, HOLD, rt=fresh)
    assert holder.stdout is not None
    line = holder.stdout.readline().split()
    if line and line[0] == "held":
        gone = lab.as_alice("import os, sys; os.unlink(sys.argv[1]); print('removed')", line[1])
        assert holder.stdin is not None
        holder.stdin.write("look\n")
        holder.stdin.flush()
        say("6 alice's locks/ first; bob holds; alice removes his record",
            f"{gone}; bob's lock: {holder.stdout.readline().strip()[:100]}")
    else:
        say("6 alice's locks/ first; bob holds", f"bob refused: {holder.stderr.read().strip()[-160:]}")  # type: ignore[union-attr]
    holder.kill()
    if lab.new:  # in the lab's folder (lab init): the same removal
        holder = lab.start(lab.bob, HOLD)
        assert holder.stdout is not None and holder.stdin is not None
        line = holder.stdout.readline().split()
        gone = lab.as_alice("import os, sys\ntry:\n os.unlink(sys.argv[1]); print('removed')\n"
                            "except OSError as e: print('refused:', e.strerror)", line[1] if line else "/none")
        holder.stdin.write("look\n")
        holder.stdin.flush()
        say("6 in the lab folder: alice removes bob's record", f"{gone}; bob's lock: "
            f"{holder.stdout.readline().strip()[:100]}")
        holder.kill()
    # 7. a locks -> elsewhere link
    linked = lab.top / "linked"
    linked.mkdir()
    os.chmod(linked, 0o1777)
    lab.as_alice("import os, sys; os.symlink(sys.argv[2], sys.argv[1] + '/locks')", str(linked), str(lab.top))
    rc, o, e = lab.py(None, HOLD.replace("for line in sys.stdin:", "for line in []:"), rt=linked)
    say("7 alice's locks -> elsewhere link: root's lock", f"rc {rc}: {(o + e).strip().splitlines()[-1][:140]}")
    if lab.new:
        made = lab.as_alice("import os, sys\ntry:\n os.symlink('/tmp', sys.argv[1] + '/locks2'); print('made')\n"
                            "except OSError as e: print('refused:', e.strerror)", str(lab.rt))
        say("7 in the lab folder: alice plants a link", made)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--code", type=Path, default=HERE, help="the checkout to attack (default: this one)")
    args = ap.parse_args()
    if os.getuid() != 0:
        print("needs root (useradd)")
        return 2
    top = Path(tempfile.mkdtemp(prefix="qta-"))
    os.chmod(top, 0o1777)  # like /tmp: where a runtime folder is made
    homes = top / "homes"
    homes.mkdir()
    try:
        with made_users(homes, "a", "b") as users:
            lab = Lab(args.code.resolve(), top, users)
            try:
                for item, answer in attacks(lab):
                    print(f"{item:60s} {answer}")
            finally:
                for p in lab.procs:
                    p.kill()
    finally:
        shutil.rmtree(top, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
