"""Session timing: the loop's jitter in a session process, and the cost of attaching.

    .venv/bin/python benchmarks/session_timing.py [--seconds 30]

1. A session process (real-time clock, 50 ms, simulator, PI in Automatic on a
   moving reference) with one client attached whose process does UI-like work
   (plotext charts of 4 x 200 points at 20 Hz, as benchmarks/loop_timing.py's
   "decimated" load) or none: p50 / p99 / max |jitter| and overruns, as LoopStats
   reports them.  Compare with loop_timing.py's `process` rows (the loop process
   the TUI used before sessions).
2. Attaching to a session whose ring buffer is full (36000 samples, 1 h at 0.1 s):
   wall time from connect to a live client holding the whole history.

Figures are printed, not asserted (the machine may be shared).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from loop_timing import ui_work  # noqa: E402

from quadtank_tui.engine.commands import SetControlMode, SetParams, SetSpeed, SetState  # noqa: E402
from quadtank_tui.engine.history import DEFAULT_CAPACITY  # noqa: E402
from quadtank_tui.engine.runner import engine_spec  # noqa: E402
from quadtank_tui.session.client import SessionClient, stop_session_at  # noqa: E402
from quadtank_tui.session.launch import SessionSpec, start_session  # noqa: E402


def jitter(seconds: float, points: int) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as tmp:
        spec = engine_spec(clock="realtime", params_dir=Path(tmp), logs_dir=Path(tmp))
        info = start_session(SessionSpec(spec, str(Path(tmp) / "run")))
        client = SessionClient(info.socket)
        for command in (SetParams({"SAMPLING TIME.TSamp": 50, "REFERENCE ONE.On": 1,
                                   "REFERENCE ONE.Amplitude": 0.05, "REFERENCE ONE.Period": 20}),
                        SetState("Run"), SetControlMode("Automatic")):
            assert client.submit(command).result(10).ok
        stop = threading.Event()
        frames: list[float] = []
        ui = threading.Thread(target=ui_work, args=(stop, frames, points), daemon=True)
        if points:
            ui.start()
        time.sleep(seconds)
        stats = client.snapshot().stats
        stop.set()
        client.close()
        stop_session_at(info.socket)
    ms = 1000.0
    return {"samples": stats.samples, "p50": stats.jitter_p50 * ms, "p99": stats.jitter_p99 * ms,
            "max": stats.jitter_max * ms, "overruns": stats.overruns, "frames": len(frames)}


def attach_cost() -> tuple[float, int]:
    with tempfile.TemporaryDirectory() as tmp:
        spec = engine_spec(clock="virtual", speed=1000.0, params_dir=Path(tmp), logs_dir=Path(tmp))
        info = start_session(SessionSpec(spec, str(Path(tmp) / "run")))
        with SessionClient(info.socket) as filler:
            filler.submit(SetSpeed(1000.0)).result(10)
            filler.submit(SetState("Run")).result(10)
            while filler.snapshot().k < DEFAULT_CAPACITY + 100:
                time.sleep(0.05)
            filler.submit(SetState("Pause")).result(10)
        t0 = time.monotonic()
        with SessionClient(info.socket) as client:
            took = time.monotonic() - t0
            rows = len(client.history()["t"])
        stop_session_at(info.socket)
    return took, rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=30.0)
    args = ap.parse_args()
    for label, points in (("no UI work", 0), ("client UI 4 x 200", 200)):
        r = jitter(args.seconds, points)
        print(f"session  50 ms  {label:18s} samples {r['samples']:5d}  jitter p50 {r['p50']:6.3f}  "
              f"p99 {r['p99']:7.3f}  max {r['max']:7.3f} ms  overruns {r['overruns']:4d}", flush=True)
    took, rows = attach_cost()
    print(f"attach with a full ring buffer: {rows} samples in {took * 1000:.0f} ms")


if __name__ == "__main__":
    main()
