"""The lock and two-user campaigns of benchmarks/hardening.py (issue 24): the DAQ
lock forged, held hostage, raced for and taken over, by this user and by two real
users made for the run.  Each campaign prints runs, failures and the worst case.

    .venv/bin/python benchmarks/hardening_locks.py              # both, 20 rounds each
    .venv/bin/python benchmarks/hardening_locks.py --only users --rounds 50
    .venv/bin/python benchmarks/hardening.py --only locks,users  # the same, in the campaign's table

`users` needs root (useradd / userdel, names qtr<pid>a / qtr<pid>b, removed at the
end); without root it is skipped.  Not a test: it prints figures, exit 1 on a failure.
"""

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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "session"))  # otherusers: users made and run as

from quadtank_tui.session import lock as lockmod  # noqa: E402
from quadtank_tui.session.lab import LabConfig  # noqa: E402
from quadtank_tui.session.lock import DaqLock, DaqLockError, DaqLockHeld, holder_of, lock_path  # noqa: E402
from otherusers import as_user, made_users  # noqa: E402

DEVICE = "127.0.0.1:15021/1"


@dataclass
class Campaign:
    """Runs, failures (what went wrong, each) and the worst case (seconds and which)."""

    name: str
    runs: int = 0
    failures: list[str] = field(default_factory=list)
    worst: tuple[float, str] = (0.0, "")

    def case(self, what: str, check: Callable[[], str | None]) -> None:
        """Run one case; `check` returns None when it went right, else why not."""
        self.runs += 1
        t0 = time.monotonic()
        try:
            why = check()
        except Exception as exc:  # noqa: BLE001 - a failure of the case, kept
            why = f"{type(exc).__name__}: {exc}"
        took = time.monotonic() - t0
        if took > self.worst[0]:
            self.worst = (took, what)
        if why is not None:
            self.failures.append(f"{what}: {why}")

    def line(self) -> str:
        return (f"{self.name:8s} {self.runs:5d} runs  {len(self.failures):3d} failures  "
                f"worst case {self.worst[0]:.2f} s ({self.worst[1]})")


# --- one user (this one): forged, hostage, racing -------------------------------------------

FLOCK_HOLDER = ("import fcntl, os, sys, time\n"
                "fd = os.open(sys.argv[1], os.O_RDONLY)\n"
                "fcntl.flock(fd, fcntl.LOCK_EX)\n"
                "print('held', flush=True)\n"
                "time.sleep(600)\n")

RACER = textwrap.dedent("""
    import sys
    from pathlib import Path
    from quadtank_tui.session.lab import LabConfig
    from quadtank_tui.session.lock import DaqLock, DaqLockHeld
    lab = LabConfig(runtime_dir=Path(sys.argv[1]))
    print("ready", flush=True)
    sys.stdin.readline()   # all start together
    try:
        DaqLock.acquire(sys.argv[2], lab)
        print("won", flush=True)
    except DaqLockHeld:
        print("refused", flush=True)
    sys.stdin.readline()
""")


def campaign_locks(c: Campaign, rounds: int, work: Path) -> None:
    for k in range(rounds):
        lab = LabConfig(runtime_dir=work / f"locks-{k}")
        lab.locks_dir.mkdir(parents=True, exist_ok=True)
        c.case("forged record (another uid, pid 1)", lambda: _forged(lab))
        c.case("flock held by another program", lambda: _hostage(lab))
        c.case("six programs racing", lambda: _race(lab))


def _forged(lab: LabConfig) -> str | None:
    path = lock_path(DEVICE, lab)
    path.write_text(json.dumps({"user": "teacher", "uid": os.getuid() + 4242, "pid": 1,
                                "since": "2026-11-26T10:00:00+00:00", "session": "teacher-1", "token": "x"}))
    if holder_of(DEVICE, lab) is not None:
        return "a forged record names a holder"
    with DaqLock.acquire(DEVICE, lab) as lock:
        return None if lock.held else "not held after acquire"


def _hostage(lab: LabConfig) -> str | None:
    p = subprocess.Popen([sys.executable, "-c", FLOCK_HOLDER, str(lab.locks_dir)], stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout is not None and p.stdout.readline() == "held\n"
        admin = lockmod.is_administrator
        lockmod.is_administrator = lambda uid, lab: False
        try:
            t0 = time.monotonic()
            try:
                DaqLock.acquire(DEVICE, lab).release()
                return "a non-administrator got the lock past a held flock"
            except DaqLockError as exc:
                if f"(pid {p.pid})" not in str(exc):
                    return f"the holder is not named: {exc}"
            if time.monotonic() - t0 > lockmod.LOCK_WAIT + 5:
                return f"refused only after {time.monotonic() - t0:.1f} s"
        finally:
            lockmod.is_administrator = admin
        lock = DaqLock.acquire(DEVICE, lab)  # this user as an administrator (root, or the params' writer)
        t0 = time.monotonic()
        lock.release()
        if time.monotonic() - t0 > lockmod.QUICK_WAIT + 2:
            return f"release waited {time.monotonic() - t0:.1f} s"
        return None
    finally:
        p.kill()
        p.wait()


def _race(lab: LabConfig) -> str | None:
    procs = [subprocess.Popen([sys.executable, "-c", RACER, str(lab.runtime_dir), DEVICE],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=ROOT) for _ in range(6)]
    try:
        if any(p.stdout is None or p.stdout.readline() != "ready\n" for p in procs):
            return "a racer did not start"
        for p in procs:  # go
            assert p.stdin is not None
            p.stdin.write("\n")
            p.stdin.flush()
        said = [p.stdout.readline().strip() for p in procs if p.stdout is not None]
        return None if sorted(said) == ["refused"] * 5 + ["won"] else f"outcomes {said}"
    finally:
        for p in procs:
            p.kill()
            p.wait()


# --- two real users -----------------------------------------------------------------------

HOLD = textwrap.dedent("""
    import sys
    from pathlib import Path
    from quadtank_tui.session.lab import LabConfig
    from quadtank_tui.session.lock import DaqLock
    lock = DaqLock.acquire(sys.argv[2], LabConfig(runtime_dir=Path(sys.argv[1])))
    print("held", flush=True)
    for line in sys.stdin:
        print(lock.lost() or "ours", flush=True)
""")

FORCE = textwrap.dedent("""
    import sys
    from pathlib import Path
    from quadtank_tui.session import lock as lockmod
    from quadtank_tui.session.lab import LabConfig
    lockmod.is_administrator = lambda uid, lab: True
    lockmod.DaqLock.acquire(sys.argv[2], LabConfig(runtime_dir=Path(sys.argv[1])), take_over=True)
    print("forced", flush=True)
""")

FORGE = textwrap.dedent("""
    import json, os, sys
    from pathlib import Path
    from quadtank_tui.session.lab import LabConfig, ensure_runtime_dir
    from quadtank_tui.session.lock import lock_path
    lab = LabConfig(runtime_dir=Path(sys.argv[1]))
    ensure_runtime_dir(lab)
    path = lock_path(sys.argv[2], lab)
    path.unlink(missing_ok=True)
    path.write_text(json.dumps({"user": "teacher", "uid": 0, "pid": 1, "since": "2026-11-26T10:00:00+00:00",
                                "session": "teacher-1", "token": "x"}))
    os.chmod(path, 0o600)
    print("forged", flush=True)
""")


def campaign_users(c: Campaign, rounds: int, work: Path) -> None:
    from quadtank_tui.session.folders import init_lab_folder

    if os.getuid() != 0 or shutil.which("useradd") is None:
        print("users: skipped (needs root and useradd)")
        return
    shared = Path(tempfile.mkdtemp(prefix="qtr-", dir="/tmp"))
    os.chmod(shared, 0o1777)
    try:
        with made_users(f"qtr{os.getpid()}a", f"qtr{os.getpid()}b") as made:
            names = (made[0], made[1])
            for k in range(rounds):
                runtime = str(shared / f"rt-{k}")
                init_lab_folder(Path(runtime))  # the lab's runtime folder, as `quadtank lab init` makes it
                c.case("stud2 forces a take-over of stud1's lock", lambda: _forced(names, runtime))
                c.case("stud2 forges 'teacher, pid 1' (0600)", lambda: _forged_by(names, runtime))
                c.case("stud2 holds the locks folder's flock", lambda: _hostage_by(names, runtime))
    finally:
        shutil.rmtree(shared, ignore_errors=True)


def _ask(p: subprocess.Popen[str]) -> str:
    assert p.stdin is not None and p.stdout is not None
    p.stdin.write("\n")
    p.stdin.flush()
    return p.stdout.readline().strip()


def _forced(names: tuple[str, str], runtime: str) -> str | None:
    holder = as_user(names[0], HOLD, runtime, DEVICE)
    try:
        assert holder.stdout is not None
        if holder.stdout.readline() != "held\n":
            return f"stud1 could not take the lock: {holder.stderr.read() if holder.stderr else ''}"
        forcer = as_user(names[1], FORCE, runtime, DEVICE)
        out, err = forcer.communicate(timeout=60)
        if out != "forced\n":
            return f"the forcing copy failed: {err[-200:]}"
        answer = _ask(holder)
        return None if answer == "ours" else f"stud1's lock: {answer!r}"
    finally:
        holder.kill()
        holder.wait()


def _forged_by(names: tuple[str, str], runtime: str) -> str | None:
    forger = as_user(names[1], FORGE, runtime, DEVICE)
    out, err = forger.communicate(timeout=60)
    if out != "forged\n":
        return f"forging failed: {err[-200:]}"
    try:
        with DaqLock.acquire(DEVICE, LabConfig(runtime_dir=Path(runtime))):  # root
            pass
    except DaqLockHeld as exc:
        return f"root refused: {exc}"
    taker = as_user(names[0], HOLD, runtime, DEVICE)
    out, err = taker.communicate(timeout=60)
    return None if out.startswith("held") else f"stud1 refused: {err.strip()[-200:]}"


def _hostage_by(names: tuple[str, str], runtime: str) -> str | None:
    Path(runtime, "locks").mkdir(parents=True, exist_ok=True)
    os.chmod(runtime, 0o1777)
    os.chmod(Path(runtime, "locks"), 0o1777)
    hostage = as_user(names[1], FLOCK_HOLDER, str(Path(runtime, "locks")))
    try:
        assert hostage.stdout is not None
        if hostage.stdout.readline() != "held\n":
            return "stud2 could not hold the flock"
        t0 = time.monotonic()
        taker = as_user(names[0], HOLD, runtime, DEVICE)
        out, err = taker.communicate(timeout=120)
        took = time.monotonic() - t0
        if f"held by {names[1]} (pid " not in err:
            return f"stud1 was not told who: {out!r} {err.strip()[-200:]!r}"
        return None if took < lockmod.LOCK_WAIT + 10 else f"stud1 waited {took:.1f} s"
    finally:
        hostage.kill()
        hostage.wait()


CAMPAIGNS = {"locks": campaign_locks, "users": campaign_users}


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--only", help="comma-separated: " + ",".join(CAMPAIGNS))
    p.add_argument("--rounds", type=int, default=20, help="rounds of each campaign's cases (default 20)")
    args = p.parse_args(argv)
    failed = 0
    with tempfile.TemporaryDirectory(prefix="hardening-locks-") as tmp:
        for name in (args.only.split(",") if args.only else list(CAMPAIGNS)):
            c = Campaign(name)
            CAMPAIGNS[name](c, args.rounds, Path(tmp))
            print(c.line(), flush=True)
            for f in c.failures[:20]:
                print(f"    {f}")
            failed += len(c.failures)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
