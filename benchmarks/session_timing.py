"""Session timing: the loop's jitter in a session process, the speed the driver
holds at x1000, and the cost of attaching.

    .venv/bin/python benchmarks/session_timing.py [--seconds 30]

1. A session process (real-time clock at 50 ms and at 10 ms, simulator, PI in
   Automatic on a moving reference) with one client attached whose process does
   UI-like work (plotext charts of 4 x 200 points at 20 Hz, as
   benchmarks/loop_timing.py's "decimated" load) or none: p50 / p99 / max |jitter|
   and overruns, as LoopStats reports them (since the session started, its
   start-up included); then "window": p99 / max of the jitter of every sample
   taken during the measured seconds only, and the session process's CPU over
   them.  At 50 ms the window is what the client saw published (every sample is);
   at 10 ms the host (this benchmark's own process) keeps every sample's jitter
   and hands it over at the end: snapshots go out every 20 ms, so the client sees
   2 samples in 5, and not a fair 2 in 5 - a sample is published when 20 ms have
   passed since the last publish, so a late one more often than an early one.
   (At 10 ms the simulator still advances its 50 ms sampling time per sample: the
   scheduler's stress only.)
2. x1000 at Ts = 50 ms with every sample logged, headless (`quadtank run --speed
   1000`) and in a session process with a client attached: the speed held, asked
   x samples / (samples + slots skipped), as the run's summary states it, and the
   session process's CPU a sample (its waits included); then the same session
   in a host of this benchmark's whose driver times its fine waits: the process's
   CPU a sample less the driving thread's waiting is the busy CPU a sample, all
   included (the loop, the log's file thread, publishing to the client).  On a
   machine where a sleep of 5 us costs 28 us of CPU (a KVM guest), the waits are
   a third of the process's CPU at x1000.  A paced virtual clock
   makes up to 20 ms of lag up in a burst (engine/clock.py, CATCH_UP): the slots
   it is behind at either end of the window are not counted, at most 0.13 % of a
   30 s window.
3. Attaching to a session whose ring buffer is full (36000 samples, 1 h at 0.1 s):
   wall time from connect to a live client holding the whole history.

Figures are printed, not asserted (the machine may be shared).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from loop_timing import ui_work  # noqa: E402

from quadtank_tui.engine.commands import LogOn, SetControlMode, SetParams, SetSpeed, SetState  # noqa: E402
from quadtank_tui.engine.headless import run_headless  # noqa: E402
from quadtank_tui.engine.history import DEFAULT_CAPACITY  # noqa: E402
from quadtank_tui.engine.runner import engine_spec  # noqa: E402
from quadtank_tui.session.client import SessionClient, stop_session_at  # noqa: E402
from quadtank_tui.session.launch import SessionSpec, start_session  # noqa: E402


#: The session's files may outlive `stop_session_at` by a moment: a temporary
#: folder that is not empty then is no reason for a benchmark to fail.
def _folder() -> tempfile.TemporaryDirectory[str]:
    return tempfile.TemporaryDirectory(ignore_cleanup_errors=True)


def _host(period: float, tmp: str, ready: Any) -> None:
    """A session's host in a process of its own with its clock at `period` (the
    interface allows 50 ms at least: below that the clock is set by hand, after the
    last command, as loop_timing.py does), serving until stopped; then every
    sample's (monotonic wall time, jitter) is left in `tmp`/JITTERS."""
    from quadtank_tui.engine.runner import build_engine

    engine = build_engine(clock="realtime", params_dir=Path(tmp), logs_dir=Path(tmp))
    for command in PREPARE:
        assert engine.submit(command).result().ok
    engine.clock.set_period(period)
    taken: list[tuple[float, float]] = []
    tick = engine.clock.tick_values

    def noted() -> tuple[float, float, int]:  # each sample's timing, as the loop records it
        scheduled, actual, missed = timing = tick()
        taken.append((actual, actual - scheduled))
        return timing

    engine.clock.tick_values = noted  # type: ignore[method-assign]
    _serve(engine, tmp, "bench-1", ready)
    np.save(Path(tmp) / JITTERS, np.array(taken, dtype=float).reshape(-1, 2))


def _serve(engine: Any, tmp: str, name: str, ready: Any) -> None:
    """Serve `engine` as a session host in this process (a host of this benchmark's)
    until stopped; its socket's path goes to `ready` once it listens."""
    from quadtank_tui.session.host import Access, SessionHost
    from quadtank_tui.session.info import SessionInfo
    from quadtank_tui.session.server import listen

    path = str(Path(tmp) / f"{name}.sock")
    info = SessionInfo(id=name, owner="bench", uid=os.getuid(), pid=os.getpid(), started="", plant="quadtank",
                       socket=path)
    host = SessionHost(engine, listen(path), info, runtime=Path(tmp), access=Access(os.getuid()))
    host.install_signal_handlers()
    ready.put(path)
    host.serve()


#: The file a host of this benchmark's leaves its samples' jitter in.
JITTERS = "jitters.npy"


#: The loop the jitter is measured on: PI in Automatic on a moving reference.
PREPARE = (SetParams({"SAMPLING TIME.TSamp": 50, "REFERENCE ONE.On": 1, "REFERENCE ONE.Amplitude": 0.05,
                      "REFERENCE ONE.Period": 20}), SetState("Run"), SetControlMode("Automatic"))


def jitter(seconds: float, points: int, tsamp_ms: int = 50) -> dict[str, float]:
    """A session process at `tsamp_ms` (50: as `quadtank` starts it; 10: a host
    process of this benchmark's, see _host) with a client drawing `points`."""
    with _folder() as tmp:
        proc = None
        if tsamp_ms == 50:
            spec = engine_spec(clock="realtime", params_dir=Path(tmp), logs_dir=Path(tmp))
            sock = start_session(SessionSpec(spec, str(Path(tmp) / "run"))).socket
        else:
            ctx = multiprocessing.get_context("fork")
            ready = ctx.Queue()
            proc = ctx.Process(target=_host, args=(tsamp_ms / 1000.0, tmp, ready))
            proc.start()
            sock = ready.get(timeout=30)
        client = SessionClient(sock)
        if proc is None:
            for command in PREPARE:
                assert client.submit(command).result(10).ok
        stop = threading.Event()
        frames: list[float] = []
        ui = threading.Thread(target=ui_work, args=(stop, frames, points), daemon=True)
        if points:
            ui.start()
        first = client.snapshot().stats
        seen: dict[int, float] = {}
        watch = threading.Thread(target=_watch, args=(client, first.samples, stop, seen), daemon=True)
        watch.start()
        pid = proc.pid if proc is not None and proc.pid is not None else client.info.pid
        t0, cpu0 = time.monotonic(), process_cpu(pid)
        time.sleep(seconds)
        t1, cpu1 = time.monotonic(), process_cpu(pid)
        stats = client.snapshot().stats
        stop.set()
        watch.join(5)
        client.close()
        stop_session_at(sock)
        if proc is not None:
            proc.join(10)
            taken = np.load(Path(tmp) / JITTERS)
            inside = (taken[:, 0] >= t0) & (taken[:, 0] <= t1)
            seen = dict(enumerate(taken[inside, 1]))
    ms = 1000.0
    window = np.sort(np.abs(np.fromiter(seen.values(), float)))
    w99 = window[min(len(window) - 1, int(0.99 * len(window)))] * ms if len(window) else float("nan")
    return {"samples": stats.samples - first.samples, "p50": stats.jitter_p50 * ms, "p99": stats.jitter_p99 * ms,
            "max": stats.jitter_max * ms, "overruns": stats.overruns, "frames": len(frames),
            "seen": len(window), "w99": w99, "wmax": window[-1] * ms if len(window) else float("nan"),
            "wover": stats.overruns - first.overruns, "cpu": 100.0 * (cpu1 - cpu0) / (t1 - t0)}


def _watch(client: SessionClient, first: int, stop: threading.Event, seen: dict[int, float]) -> None:
    """The jitter of each sample of the window that a published snapshot shows
    (`jitter_last`): the session's own percentiles count since it started, its
    start-up included, and at 50 ms p99 is the 6th-worst of 600 samples.  Snapshots
    are published every 20 ms: at 50 ms every sample is seen (at 10 ms the host's
    own record is used instead: see the module's docstring)."""
    while not stop.is_set():
        stats = client.snapshot().stats
        if stats.samples > first:
            seen[stats.samples] = stats.jitter_last
        time.sleep(0.005)


def _ts50(folder: Path) -> Path:
    par = folder / "ts50.par"
    par.write_text("SAMPLING TIME\nTSamp 50\n")
    return par


def headless_speed(seconds: float) -> str:
    """`quadtank run --speed 1000` at 50 ms for `seconds` of wall time, logging
    every sample: its summary's speed line."""
    with _folder() as tmp:
        folder = Path(tmp)
        result = run_headless(par=str(_ts50(folder)), script=None, duration=1000.0 * seconds,
                              out=folder / "run.log", clock="virtual", speed=1000.0, params_dir=folder)
    return next(line for line in result.text.splitlines() if line.startswith("speed"))


def session_speed(seconds: float) -> dict[str, float]:
    """A session process at x1000 and 50 ms for `seconds`, logging, a client attached."""
    with _folder() as tmp:
        spec = engine_spec(clock="virtual", speed=1000.0, params_dir=Path(tmp), logs_dir=Path(tmp))
        info = start_session(SessionSpec(spec, str(Path(tmp) / "run")))
        return _x1000_window(info.socket, info.pid, seconds)


def _x1000_window(sock: str, pid: int, seconds: float, waited: Any = None, settle: float = 0.0) -> dict[str, float]:
    """The session at `sock` (process `pid`) set to x1000 at 50 ms, logging, and
    run; after `settle` s, `seconds` of it measured with a client attached: the
    samples, the slots skipped, the speed held and the process's CPU a sample (and,
    with `waited`, a shared value of the driver's waiting, that part of it).  The
    session is stopped at the end."""
    with SessionClient(sock) as client:
        for command in (SetParams({"SAMPLING TIME.TSamp": 50}), SetSpeed(1000.0), LogOn(points=10**7),
                        SetState("Run")):
            assert client.submit(command).result(10).ok
        time.sleep(settle)
        w0 = waited.value if waited is not None else 0.0
        first, cpu0 = client.snapshot().stats, process_cpu(pid)
        time.sleep(seconds)
        last, cpu1 = client.snapshot().stats, process_cpu(pid)
        w1 = waited.value if waited is not None else 0.0
    stop_session_at(sock)
    samples, skipped = last.samples - first.samples, last.skipped - first.skipped
    n = max(1, samples)
    return {"samples": samples, "skipped": skipped, "held": 1000.0 * samples / max(1, samples + skipped),
            "cpu_us": 1e6 * (cpu1 - cpu0) / n, "wait_us": 1e6 * (w1 - w0) / n}


def _waits_host(tmp: str, ready: Any, waited: Any) -> None:
    """session_speed's session, in a process of this benchmark's whose driver times
    its fine waits: their CPU (the driving thread's, seconds) adds up in `waited`."""
    from quadtank_tui.engine import driver
    from quadtank_tui.engine.runner import build_engine

    fine_wait = driver.fine_wait

    def timed(deadline: float, spin: float = 0.0) -> None:
        c = time.thread_time()
        fine_wait(deadline, spin)
        with waited.get_lock():
            waited.value += time.thread_time() - c

    driver.fine_wait = timed  # the drive looks it up at each wait
    engine = build_engine(clock="virtual", speed=1000.0, params_dir=Path(tmp), logs_dir=Path(tmp))
    _serve(engine, tmp, "bench-2", ready)


def session_busy(seconds: float) -> dict[str, float]:
    """session_speed's run with the driver's fine waits timed (a host of this
    benchmark's, see _waits_host): the process's CPU a sample with and without the
    driving thread's waiting.  On a machine where a sleep of a few microseconds
    costs tens of microseconds of CPU, the process's CPU at x1000 is mostly the
    waits' (each is 50 us less the sample's work: a sleep of it, or a spin)."""
    with _folder() as tmp:
        ctx = multiprocessing.get_context("fork")
        ready, waited = ctx.Queue(), ctx.Value("d", 0.0)
        proc = ctx.Process(target=_waits_host, args=(tmp, ready, waited))
        proc.start()
        sock = ready.get(timeout=30)
        assert proc.pid is not None
        # settle: the first waits and the log's start behind it
        r = _x1000_window(sock, proc.pid, seconds, waited, settle=1.0)
        proc.join(10)
    return r


def process_cpu(pid: int) -> float:
    """CPU seconds (user + system) process `pid` has used (Linux /proc; nan elsewhere)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return float("nan")
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def attach_cost() -> tuple[float, int]:
    with _folder() as tmp:
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
    ap.add_argument("--jitter-only", action="store_true", help="part 1 only (the sessions at 50 and 10 ms)")
    ap.add_argument("--periods", type=int, nargs="+", default=[50, 10], metavar="MS",
                    help="part 1's sampling times (50: a session as quadtank starts it; others: a host of this "
                    "benchmark's)")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} (2 cores shared: compare runs made close together)", flush=True)
    for tsamp_ms in args.periods:
        for label, points in (("no UI work", 0), ("client UI 4 x 200", 200)):
            r = jitter(args.seconds, points, tsamp_ms)
            print(f"session  {tsamp_ms:2d} ms  {label:18s} samples {r['samples']:5d}  jitter p50 {r['p50']:6.3f}  "
                  f"p99 {r['p99']:7.3f}  max {r['max']:7.3f} ms  overruns {r['overruns']:4d}  "
                  f"window ({r['seen']:.0f} samples) p99 {r['w99']:6.3f}  max {r['wmax']:6.3f} ms  "
                  f"overruns {r['wover']:.0f}  session CPU {r['cpu']:4.1f} %  "
                  f"(load {os.getloadavg()[0]:.1f})", flush=True)
    if args.jitter_only:
        return
    print(f"headless x1000 at 50 ms, logging, {args.seconds:g} s: {headless_speed(args.seconds)}", flush=True)
    r = session_speed(args.seconds)
    print(f"session  x1000 at 50 ms, logging, a client, {args.seconds:g} s: {r['samples']:.0f} samples, "
          f"{r['skipped']:.0f} slots skipped: x{r['held']:.0f} held; the session process "
          f"{r['cpu_us']:.1f} us CPU a sample", flush=True)
    r = session_busy(args.seconds)
    print(f"session  x1000 at 50 ms, logging, a client, {args.seconds:g} s, the driver's waits timed: "
          f"x{r['held']:.0f} held, {r['skipped']:.0f} slots skipped; the session process {r['cpu_us']:.1f} us CPU "
          f"a sample, {r['wait_us']:.1f} of them waiting: {r['cpu_us'] - r['wait_us']:.1f} us busy a sample, "
          "all included", flush=True)
    took, rows = attach_cost()
    print(f"attach with a full ring buffer: {rows} samples in {took * 1000:.0f} ms")
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
