"""Loop timing: the driver on the real-time clock at 50 ms and 10 ms while the same process renders.

    .venv/bin/python benchmarks/loop_timing.py [--seconds 60] [--switch-interval MS] [--log]

For each period the one driver (engine/driver.py, inline: the real-time clock,
simulator, PI in Automatic) runs for `--seconds` on this process's main thread,
while another thread of this process does UI-like work: building plotext charts of 4 series at 20 Hz.  Three
loads: none (the clock alone), 4 x 200 points (5000 samples decimated to a
terminal's width, what a trend widget should draw) and 4 x 5000 points (the issue's
load: one such frame takes far longer than 50 ms in pure Python, so that thread
never rests, the worst case for the GIL).  Prints p50 / p99 / max of |jitter|
(actual minus scheduled sample start, as LoopStats reports them) and the overruns.

The 10 ms clock is below the interface's 50 ms minimum sampling time: it stresses
the scheduler only (the simulator still advances the 50 ms sampling time per
sample).  `--log` logs every sample to a `.log` in a temporary folder meanwhile (the
disk's part: rows written as they come, fsynced each second).  Figures are printed,
not asserted.  This is the driver's pacing against the GIL; the TUI's loop runs in
a session process (lab or private, the same driver, serving its clients on its
event loop): benchmarks/session_timing.py measures that, with a client drawing.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import plotext

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from quadtank_tui.engine.commands import LogOn, SetControlMode, SetParams, SetState  # noqa: E402
from quadtank_tui.engine.driver import Driver  # noqa: E402
from quadtank_tui.engine.runner import Engine, build_engine  # noqa: E402

POINTS = 5000
UI_HZ = 20.0


def ui_work(stop: threading.Event, frames: list[float], points: int) -> None:
    """Render 4 x `points` points with plotext (its own figure, not the global one)."""
    x = (np.arange(points) * 0.05).tolist()
    series = [np.sin(np.arange(points) * 0.01 + j).tolist() for j in range(4)]
    next_frame = time.monotonic()
    while not stop.is_set():
        t0 = time.monotonic()
        fig = plotext._figure._figure_class()  # a private figure per thread, as each trend has
        fig.plotsize(120, 30)
        for s in series:
            fig.plot(x, s)
        fig.build()
        frames.append(time.monotonic() - t0)
        next_frame += 1.0 / UI_HZ
        delay = next_frame - time.monotonic()
        if delay > 0:
            stop.wait(delay)
        else:
            next_frame = time.monotonic()


def prepare(period: float, log: bool, engine: Engine) -> None:
    """Simulator, PI in Automatic on a moving reference, clock at `period`, logging if `log`."""
    engine.submit(SetParams({"SAMPLING TIME.TSamp": 50, "REFERENCE ONE.On": 1,
                             "REFERENCE ONE.Amplitude": 0.05, "REFERENCE ONE.Period": 20}))
    engine.submit(SetState("Run"))
    engine.submit(SetControlMode("Automatic"))
    if log:
        engine.submit(LogOn(points=10**7))
    engine.clock.set_period(period)  # after the last command (commands resync it to TSamp)


def measure(period: float, seconds: float, points: int, log: bool = False) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as tmp:
        engine = build_engine(clock="realtime", params_dir=Path(tmp), logs_dir=Path(tmp))
        prepare(period, log, engine)
        stop = threading.Event()
        frames: list[float] = []
        ui = threading.Thread(target=ui_work, args=(stop, frames, points), daemon=True)
        if points:
            ui.start()
        try:
            Driver(engine, samples=round(seconds / period)).run()  # paced by the real-time clock
        finally:
            engine.stop()
            stop.set()
        if points:
            ui.join()
        stats = engine.snapshot().stats
    ms = 1000.0
    return {
        "samples": stats.samples, "p50": stats.jitter_p50 * ms, "p99": stats.jitter_p99 * ms,
        "max": stats.jitter_max * ms, "overruns": stats.overruns,
        "frames": len(frames), "frame_ms": float(np.median(frames) * ms) if frames else 0.0,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--switch-interval", type=float, default=None, metavar="MS",
                    help="set the GIL switch interval of this process (ms; Python's default: 5)")
    ap.add_argument("--log", action="store_true", help="log every sample to a temporary .log meanwhile")
    args = ap.parse_args()
    print(f"real-time clock, {args.seconds:g} s per run; UI load: another thread of this process "
          f"building plotext charts of 4 series at up to {UI_HZ:g} Hz")
    if args.log:
        print("logging every sample to a .log in a temporary folder")
    print("jitter = |actual - scheduled sample start|, percentiles as the engine reports them "
          "(upper bin edges, <= 4.7 % high)")
    loads = (("no UI thread", 0), ("UI 4 x 200 (decimated)", 200), ("UI 4 x 5000 (full)", POINTS))
    for period in (0.050, 0.010):
        for label, points in loads:
            if args.switch_interval is not None:
                sys.setswitchinterval(args.switch_interval / 1000.0)
            r = measure(period, args.seconds, points, args.log)
            ui = f"{r['frames']} frames, {r['frame_ms']:.0f} ms each" if points else "-"
            print(f"driver  {period * 1000:3.0f} ms  {label:24s} samples {r['samples']:5d}  "
                  f"jitter p50 {r['p50']:6.3f}  p99 {r['p99']:7.3f}  max {r['max']:7.3f} ms  "
                  f"overruns {r['overruns']:4d}  (UI: {ui})", flush=True)
    print(f"GIL switch interval: {sys.getswitchinterval() * 1000:.2f} ms here; "
          "target: p99 < 2 ms, no overruns at 50 ms")


if __name__ == "__main__":
    main()
