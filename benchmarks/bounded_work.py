"""Bounded work on hostile files (issue 24): the time and peak memory of reading a
big log, a line of millions of columns, and a huge model expression, each in a
fresh subprocess (its own peak RSS, from resource.getrusage).

    .venv/bin/python benchmarks/bounded_work.py              # all cases
    .venv/bin/python benchmarks/bounded_work.py --only expr
    .venv/bin/python benchmarks/bounded_work.py --code /work/main   # another checkout's code (before/after)

Cases:
  log50       a 50 MB .log (about 560,000 rows) through `quadtank log info` and `quadtank identify`
  columns     one data line of 10 million columns through `quadtank log info`
  expr        a 130 KB model expression through `quadtank design --model`

Each prints: the case, the exit status, the wall time, the child's peak RSS and the
first line of what it said.  The big files are generated in a temporary folder
(never in the repository).  Not a test: it prints figures.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Sequence

ROOT = Path(__file__).resolve().parents[1]
CASES = ("log50", "columns", "expr")

#: One child's figures: `quadtank` run through the code under test, its peak RSS read back.
CHILD = """
import resource, sys, time
sys.argv = ["quadtank"] + sys.argv[1:]
t0 = time.monotonic()
from quadtank_tui.cli import main
try:
    rc = main()
except SystemExit as exc:
    rc = exc.code
print(f"@@ {rc} {time.monotonic() - t0:.2f} {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f}",
      file=sys.stderr)
"""


def run(label: str, argv: list[str], code: Path, cwd: Path, timeout: float = 600) -> None:
    env = dict(os.environ, PYTHONPATH=str(code), NO_COLOR="1")
    try:
        p = subprocess.run([sys.executable, "-c", CHILD, *argv], cwd=cwd, env=env, capture_output=True,
                           text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        print(f"{label:<28} TIMEOUT after {timeout:.0f} s")
        return
    figures = [line for line in p.stderr.splitlines() if line.startswith("@@ ")]
    said = next((line for line in (p.stderr + p.stdout).splitlines() if line and not line.startswith("@@")), "")
    if not figures:
        print(f"{label:<28} crashed (exit {p.returncode}): {said[:100]}")
        return
    rc, secs, rss = figures[-1].split()[1:]
    print(f"{label:<28} exit {rc:>3}  {float(secs):7.2f} s  peak RSS {int(rss):6d} MB   {said[:90]}")


def make_log(path: Path, megabytes: float) -> Path:
    """A valid .log of about `megabytes` MB: the layout `quadtank run` writes, a
    first-order response of each tank to pseudo-random pump steps (identify needs
    excitation)."""
    import random

    rng = random.Random(24)
    with path.open("w") as f:
        f.write("% TANK LOG-file\n% Created on: Nov 26 12:00:00 2026\n"
                "% Logged variables: y1 y2 y3 y4 u1 u2   TSamp: 0.1s\n\n")
        y = [0.5, 0.5, 0.2, 0.2]
        u = [0.3, 0.3]
        k = 0
        while f.tell() < megabytes * 1e6:
            if k % 200 == 0:
                u = [0.3 + rng.choice((-0.05, 0.05)), 0.3 + rng.choice((-0.05, 0.05))]
            y = [y[0] + 0.01 * (1.6 * u[0] - y[0]), y[1] + 0.01 * (1.6 * u[1] - y[1]),
                 y[2] + 0.01 * (0.7 * u[1] - y[2]), y[3] + 0.01 * (0.7 * u[0] - y[3])]
            f.write("  ".join(f"{v:f}" for v in (*y, *u)) + "\n")
            k += 1
    return path


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--only", help="comma-separated: " + ",".join(CASES))
    p.add_argument("--code", default=str(ROOT), help="the checkout whose quadtank_tui runs (default: this one)")
    args = p.parse_args(argv)
    chosen = args.only.split(",") if args.only else list(CASES)
    code = Path(args.code).resolve()
    print(f"code: {code}")
    with tempfile.TemporaryDirectory(prefix="bounded-") as tmp:
        work = Path(tmp)
        (work / "logs").mkdir()
        if "log50" in chosen:
            log = make_log(work / "logs" / "big.log", 50)
            print(f"log50: {log.stat().st_size / 1e6:.1f} MB, {sum(1 for _ in log.open()) - 4} rows")
            run("log info (50 MB)", ["log", "info", str(log)], code, work)
            run("identify (50 MB)", ["identify", str(log)], code, work)
        if "columns" in chosen:
            wide = work / "logs" / "wide.log"
            with wide.open("w") as f:
                f.write("% TANK LOG-file\n% Logged variables: y1 y2 u1 u2   TSamp: 0.1s\n\n")
                f.write(" ".join(["0.5"] * 10_000_000) + "\n")
            print(f"columns: {wide.stat().st_size / 1e6:.1f} MB, one line of 10,000,000 columns")
            run("log info (10M columns)", ["log", "info", str(wide)], code, work)
        if "expr" in chosen:
            for name, text in expressions().items():
                run(f"design --model ({name})", ["design", "--model", text], code, work)
    return 0


def expressions() -> dict[str, str]:
    """Hostile model expressions of about 130 KB, each a different way to make work."""
    n = 130_000
    return {
        "130 KB sum": "1/(s+1)" + "+0*s" * ((n - 7) // 4),
        "130 KB product": "1/(" + "(0.5*s+1)" * ((n - 4) // 10) + ")",
        "nested parentheses": "(" * (n // 2 - 1) + "s" + ")" * (n // 2 - 1),
        "1000-char product": "1/(" + "(0.5*s+1)" * 99 + ")",
    }


if __name__ == "__main__":
    sys.exit(main())
