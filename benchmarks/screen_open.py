"""Screen and window opening: the CPU milliseconds the TUI spends between a key and
the screen or window it opens, drawn.

    .venv/bin/python benchmarks/screen_open.py [--runs 5] [--size 120x40]

Each run builds a fresh app on the simulator (a manual clock: nothing moves by
itself) in Textual's headless driver at `--size`, then, as a user would: `S` opens
Setup (its first visit), its windows `s`, `i`, `f`, `t` open and Esc closes
each, Esc goes back to Main; then `d` Design, `y` Identify and F1 Help, each closed
again, and the Main windows `t`, `i`, `h`, `v`.  A key's figure is the process's
CPU time (all its threads: workers included) from the key until the app is idle
again, so the machine's other programs do not count (over SSH the terminal's bytes
come on top).  The first run pays Python's one-off imports and is left out; the
median of the others is printed, with the first visit of a screen in a fresh app
(what a student pays once per screen) and a later visit (Setup again).  Figures,
not assertions.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import statistics
import sys
import tempfile
import time
from collections import defaultdict
from datetime import datetime
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from quadtank_tui.engine.runner import build_engine  # noqa: E402
from quadtank_tui.files.shipped import write_shipped  # noqa: E402
from quadtank_tui.ui.app import build_app  # noqa: E402
from quadtank_tui.ui.widgets.analysis_panel import warm_up  # noqa: E402

#: (label, keys pressed, keys that close it again).
STEPS = [
    ("Setup (first visit)", ["S"], []),
    ("  Sampling window", ["s"], ["escape"]),
    ("  Reference window", ["i"], ["escape"]),
    ("  Files window", ["f"], ["escape"]),
    ("  Type window", ["t"], ["escape"]),
    ("Main (back)", ["escape"], []),
    ("Setup (again)", ["S"], ["escape"]),
    ("Design (first visit)", ["d"], ["escape"]),
    ("Identify (first visit)", ["y"], ["escape"]),
    ("Help (first visit)", ["f1"], ["escape"]),
    ("Main: Type window", ["t"], ["escape"]),
    ("Main: Input window", ["i"], ["escape"]),
    ("Main: Tank window", ["h"], ["escape"]),
    ("Main: Pump window", ["v"], ["escape"]),
]


async def one_run(size: tuple[int, int]) -> dict[str, tuple[float, str]]:
    """CPU seconds per step of STEPS, in a fresh app, and the screen it ended on."""
    engine = build_engine(clock="manual", params_dir="params", logs_dir="logs", epoch=datetime(2026, 1, 5, 9))
    app = build_app(engine, refresh_interval=0.05, wall_clock=lambda: 0.0)
    cpu: dict[str, tuple[float, str]] = {}
    try:
        async with app.run_test(size=size) as pilot:
            await pilot.pause()
            for label, keys, close in STEPS:
                start = time.process_time()
                await pilot.press(*keys)
                await pilot.pause()
                cpu[label] = (time.process_time() - start, type(app.screen).__name__)
                if close:
                    await pilot.press(*close)
                    await pilot.pause()
    finally:
        engine.stop()
    return cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5, help="fresh apps measured (after one left out)")
    ap.add_argument("--size", default="120x40", help="terminal size, COLSxROWS")
    args = ap.parse_args()
    cols, rows = (int(v) for v in args.size.split("x"))
    warm_up()  # the analysis stack, as the Main screen loads it after its first frame
    figures: dict[str, list[float]] = defaultdict(list)
    shown: dict[str, str] = {}
    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(tmp)
        write_shipped("params")
        Path("logs").mkdir()
        for run in range(args.runs + 1):
            cpu = asyncio.run(one_run((cols, rows)))
            if run:
                for label, (seconds, screen) in cpu.items():
                    figures[label].append(seconds)
                    shown[label] = screen
    print(f"CPU ms from the key until idle, median of {args.runs} fresh apps at {cols}x{rows} "
          f"(load average {os.getloadavg()[0]:.1f}), and the screen shown:")
    for label, _keys, _close in STEPS:
        print(f"  {label:24s} {statistics.median(figures[label]) * 1000:7.0f}  ({shown[label]})")


if __name__ == "__main__":
    main()
