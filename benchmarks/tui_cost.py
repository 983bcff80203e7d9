"""What the TUI costs a terminal, a link and the machine (issue 17, "Cost over SSH").

    .venv/bin/python benchmarks/tui_cost.py [--runs 3] [--seconds 5] [--settle 6]
                                            [--sizes 120x40 80x24] [--states paused ts1 ts01]

Each run starts the real program (`.venv/bin/quadtank`, the simulator, the loop in
its own process) in a pseudo-terminal of the given size, as a user's terminal or
tmux pane would, and reads everything it writes.  States:

- paused: as launched (Pause, Ts 0.1 s), nothing on the screen changes;
- ts1:    Run at Ts = 1 s, x1;
- ts01:   Run at Ts = 0.1 s, x1;
- ts01pump, ts01log (only when asked for): the same with the Pump window or the
  Logging window open (live windows, updated on the screen's timer);
- pausedpump (only when asked for): paused with the Pump window open;

(Ts comes from a `--par` file written for the run; `r` is typed to Run.)  After
`--settle` seconds the next `--seconds` are measured: bytes per second written to
the terminal, and the CPU share of the TUI process and of the loop process from
/proc/PID/stat (utime + stime over the window, % of one core).  The settling
time lets the one-off start-up work end first (the TUI imports python-control
in a thread after its first frame, 1-4 s of CPU on this machine); "start KB" is
everything written until the window.  Also measured: the first frame (launch
until the status line, process image, input panels and footer have all been
written), the TUI's CPU seconds by then (the work itself, whatever the machine's
load), and the Setup screen's first open (`S` typed after the window: until its
status line is written, and until its analysis panel shows the zeros).  Medians
of `--runs` runs are printed; figures, not assertions.  The package's bytecode is
compiled first, as `make run` does.  On a shared machine the
times include waiting for a core; the CPU shares do not.
"""

from __future__ import annotations

import argparse
import fcntl
import json
import os
import re
import select
import signal
import statistics
import struct
import subprocess
import sys
import tempfile
import termios
import threading
import time
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from quadtank_tui.files.par import format_par, read_par  # noqa: E402

#: Words each part of the Main screen writes (status line, process image, input
#: panels, footer): the first frame is complete when all have been written.
FIRST_FRAME = ("Ts ", "P2", "now", "Setup")
SETUP_SHOWN = "SETUP"
SETUP_ANALYSED = "Zeros"
ANSI = re.compile(rb"\x1b(\[[0-9;?<>=$]*[ -/]*[@-~]|\][^\x07]*\x07|[PX^_].*?\x1b\\|.)")
CLK_TCK = os.sysconf("SC_CLK_TCK")
#: state: (TSamp in ms, the keys typed after the first frame, the keys that go
#: back to Main before Setup is opened).  ts01pump, ts01log, pausedpump (not run by
#: default): a live window open over a running or paused screen.
STATES = {"paused": (100, b"", b""), "ts1": (1000, b"r", b""), "ts01": (100, b"r", b""),
          "ts01pump": (100, b"rv", b"v"), "ts01log": (100, b"rl", b"\x1b"),
          "pausedpump": (100, b"v", b"v")}
DEFAULT_STATES = ["paused", "ts1", "ts01"]


class Terminal:
    """A pseudo-terminal whose slave end the program writes; a thread drains the
    master end and keeps (time, bytes) of every read and the text without escapes."""

    def __init__(self, cols: int, rows: int) -> None:
        self.master, self.slave = os.openpty()
        fcntl.ioctl(self.slave, termios.TIOCSWINSZ, struct.pack("HHHH", rows, cols, 0, 0))
        self.chunks: list[tuple[float, int]] = []
        self.raw = bytearray()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._drain, daemon=True)

    def start(self) -> None:
        self._thread.start()

    def _drain(self) -> None:
        while True:
            ready, _, _ = select.select([self.master], [], [], 0.2)
            if not ready:
                continue
            try:
                data = os.read(self.master, 1 << 16)
            except OSError:
                return
            if not data:
                return
            now = time.monotonic()
            with self._lock:
                self.chunks.append((now, len(data)))
                self.raw += data

    def type(self, keys: bytes) -> None:
        os.write(self.master, keys)

    def bytes_between(self, t0: float, t1: float) -> int:
        with self._lock:
            return sum(n for t, n in self.chunks if t0 <= t < t1)

    def wait_for(self, words: tuple[str, ...], start: int, timeout: float) -> float | None:
        """Monotonic time at which all `words` had been written after byte offset
        `start`, or None after `timeout` s."""
        end = time.monotonic() + timeout
        wanted = [w.encode() for w in words]
        while time.monotonic() < end:
            with self._lock:
                text = ANSI.sub(b"", bytes(self.raw[start:]))
            if all(w in text for w in wanted):
                return time.monotonic()
            time.sleep(0.01)
        return None

    def offset(self) -> int:
        with self._lock:
            return len(self.raw)

    def close(self) -> None:
        os.close(self.master)
        self._thread.join(timeout=1.0)


def cpu_seconds(pid: int) -> float:
    """utime + stime of a process so far, s (0 if it is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def session_records(runtime: Path) -> list[dict]:
    """The session records in a runtime folder (issue 16: the loop runs in a session)."""
    out = []
    for path in sorted(runtime.glob("users/*/*.json")):  # each user's folder of sessions
        try:
            out.append(json.loads(path.read_text()))
        except (OSError, ValueError):
            continue
    return out


def loop_process(parent: int, runtime: Path, timeout: float = 10.0) -> int | None:
    """The loop process: the session process named in the runtime folder, else (with
    --no-session, a private session) the parent's child running session.launch."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        for record in session_records(runtime):
            return int(record["pid"])
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            try:
                stat = (entry / "stat").read_text().rsplit(")", 1)[1].split()
                cmd = (entry / "cmdline").read_bytes()
            except OSError:
                continue
            if int(stat[1]) == parent and b"quadtank_tui.session.launch" in cmd:
                return int(entry.name)
        time.sleep(0.05)
    return None


@dataclass
class Run:
    kbps: float
    tui_cpu: float
    loop_cpu: float
    first_frame: float
    first_cpu: float
    start_kb: float
    setup_shown: float
    setup_analysed: float


def par_file(folder: Path, tsamp_ms: int) -> Path:
    params = read_par(ROOT / "params" / "default.par").params.with_value("SAMPLING TIME.TSamp", tsamp_ms)
    path = folder / f"ts{tsamp_ms}.par"
    path.write_text(format_par(params, datetime(2026, 1, 1)), encoding="ascii")
    return path


def one_run(program: Path, size: tuple[int, int], state: str, settle: float, seconds: float,
            folder: Path) -> Run:
    tsamp, keys, back = STATES[state]
    term = Terminal(*size)
    env = dict(os.environ, TERM="xterm-256color", COLORTERM="truecolor", COLUMNS=str(size[0]),
               LINES=str(size[1]))
    env.pop("NO_COLOR", None)
    # Each run starts its own session in its own runtime folder, stopped at the end:
    # a session outlives its TUI, and a later run would attach to it.
    runtime = Path(tempfile.mkdtemp(prefix="rt-", dir=folder))
    env["QUADTANK_RUNTIME"] = str(runtime)
    term.start()
    t0 = time.monotonic()
    proc = subprocess.Popen([str(program), "--par", str(par_file(folder, tsamp))], cwd=folder,
                            stdin=term.slave, stdout=term.slave, stderr=term.slave, env=env,
                            start_new_session=True)
    os.close(term.slave)
    nan = float("nan")
    try:
        shown = term.wait_for(FIRST_FRAME, 0, 30.0)
        first = (shown - t0) if shown is not None else nan
        first_cpu = cpu_seconds(proc.pid)
        loop_pid = loop_process(proc.pid, runtime)
        for key in keys:
            term.type(bytes([key]))
            time.sleep(0.2)
        time.sleep(settle)
        start_kb = term.bytes_between(t0, time.monotonic()) / 1024
        w0 = time.monotonic()
        c_tui, c_loop = cpu_seconds(proc.pid), cpu_seconds(loop_pid) if loop_pid else 0.0
        time.sleep(seconds)
        w1 = time.monotonic()
        d_tui = cpu_seconds(proc.pid) - c_tui
        d_loop = (cpu_seconds(loop_pid) - c_loop) if loop_pid else nan
        written = term.bytes_between(w0, w1)
        if back:
            term.type(back)
            time.sleep(0.5)
        at = term.offset()
        pressed = time.monotonic()
        term.type(b"S")
        seen = term.wait_for((SETUP_SHOWN,), at, 20.0)
        analysed = term.wait_for((SETUP_ANALYSED,), at, 20.0)
        return Run(
            kbps=written / 1024 / (w1 - w0),
            tui_cpu=100 * d_tui / (w1 - w0), loop_cpu=100 * d_loop / (w1 - w0),
            first_frame=first, first_cpu=first_cpu, start_kb=start_kb,
            setup_shown=(seen - pressed) if seen else nan,
            setup_analysed=(analysed - pressed) if analysed else nan,
        )
    finally:
        try:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(timeout=5)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait()
        term.close()
        for record in session_records(runtime):
            subprocess.run([str(program), "stop", str(record["id"])], env=env, cwd=folder,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=30)


@dataclass
class Row:
    size: str
    state: str
    runs: list[Run] = field(default_factory=list)

    def median(self, name: str) -> float:
        return statistics.median(getattr(r, name) for r in self.runs)


COLUMNS = (("KB/s", "kbps", "{:8.1f}"), ("TUI %", "tui_cpu", "{:7.1f}"), ("loop %", "loop_cpu", "{:7.1f}"),
           ("frame s", "first_frame", "{:8.2f}"), ("frame CPU s", "first_cpu", "{:12.2f}"),
           ("start KB", "start_kb", "{:9.0f}"),
           ("Setup s", "setup_shown", "{:8.2f}"), ("analysis s", "setup_analysed", "{:11.2f}"))


def table(rows: list[Row]) -> str:
    head = f"{'size':>7} {'state':>7} " + " ".join(
        f"{h:>{len(fmt.format(0.0))}}" for h, _, fmt in COLUMNS)
    lines = [head]
    for row in rows:
        lines.append(f"{row.size:>7} {row.state:>7} " + " ".join(
            fmt.format(row.median(name)) for _, name, fmt in COLUMNS))
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=5.0, help="measured window, s")
    ap.add_argument("--settle", type=float, default=6.0, help="wait after the first frame, s")
    ap.add_argument("--sizes", nargs="+", default=["120x40", "80x24"])
    ap.add_argument("--states", nargs="+", default=DEFAULT_STATES, choices=list(STATES))
    ap.add_argument("--program", type=Path, default=ROOT / ".venv" / "bin" / "quadtank")
    args = ap.parse_args()
    # The package's bytecode, as `make run` has it: otherwise every start compiles
    # the modules again when PYTHONDONTWRITEBYTECODE is set.
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(ROOT / "quadtank_tui")], check=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "params").mkdir()
        (folder / "logs").mkdir()
        for size in args.sizes:
            cols, lines = (int(v) for v in size.split("x"))
            for state in args.states:
                row = Row(size, state)
                for _ in range(args.runs):
                    row.runs.append(one_run(args.program, (cols, lines), state, args.settle,
                                            args.seconds, folder))
                rows.append(row)
                print(f"{size} {state}: " + ", ".join(
                    f"{r.kbps:.1f} KB/s {r.tui_cpu:.1f}%/{r.loop_cpu:.1f}%" for r in row.runs),
                    file=sys.stderr, flush=True)
    print(f"medians of {args.runs} runs; window {args.seconds:g} s after {args.settle:g} s; "
          f"CPU in % of one core (TUI process, loop process)")
    print(table(rows))


if __name__ == "__main__":
    main()
