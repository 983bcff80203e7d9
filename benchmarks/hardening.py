"""The tester's campaign of issue 18, reproducible: hostile input and faults through
the real code paths, each case judged, every failure kept with its input.

    .venv/bin/python benchmarks/hardening.py                 # small counts, a few minutes
    .venv/bin/python benchmarks/hardening.py --issue         # the issue's counts
    .venv/bin/python benchmarks/hardening.py --only par,scripts --par 5009 --seed 3
    .venv/bin/python benchmarks/hardening.py --replay /tmp/hardening-xyz/keys-0001.txt --shrink

Campaigns (each prints: cases run, accepted, refused cleanly, failures):
  keys     random keys through the TUI (Textual's pilot, the real app on a manual-clock engine)
  fields   bad values typed into every field of the windows (Main and Setup)
  par      mutated .par files through files.par (and `quadtank analyze --par`)
  scripts  mutated scripts through files.script, accepted ones run by `quadtank run`
  daq      mutated DAQ configurations through daq.config (and `quadtank daq check`)
  kills    SIGKILL of `quadtank run` while logging: the partial log and its recovery
  devices  a killed / frozen / slow / hung / lying Modbus device under `quadtank run --daq`
  hosts    `quadtank run --daq` itself killed (SIGKILL) or stopped (SIGSTOP, then SIGCONT) while
           its pumps run, on a rig with the LabJack watchdog and one without: the time to 0 V
  paths    hostile path names given to every command that takes a file
  locks    the DAQ lock forged, its folder's flock held hostage, six programs racing (hardening_locks.py)
  users    two real users (root: useradd): a forced take-over, a forged record, a held flock
  sockets  another user against a session: malformed lines, 1,017 idle connections, 900 x 1 MB
           lines (benchmarks/socket_campaign.py): host RSS, CPU, the owner able to attach

A failure is a traceback, a hang, a wrong exit status, an invalid value accepted or a
lost row; its input is saved under the output folder (printed at the end).  Not a
test (pytest does not collect benchmarks/); it exits 1 if anything failed.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import dataclasses
import io
import math
import os
import random
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from pathlib import Path
from typing import Any, AsyncIterator, Callable, Iterator, Sequence

ROOT = Path(__file__).resolve().parents[1]
PARAMS = ROOT / "params"
ISSUE_COUNTS = {"keys": 11_724, "fields": 570, "par": 5_009, "scripts": 700, "daq": 500, "kills": 29,
                "hosts": 20, "sockets": 500}
SMALL_COUNTS = {"keys": 600, "fields": 120, "par": 400, "scripts": 60, "daq": 80, "kills": 3, "hosts": 4,
                "sockets": 100}
CAMPAIGNS = ("keys", "fields", "par", "scripts", "daq", "kills", "devices", "hosts", "paths", "locks", "users",
             "sockets")


# --- bookkeeping ---------------------------------------------------------------------------

@dataclasses.dataclass
class Failure:
    kind: str      # traceback | hang | exit status | invalid value accepted | lost row | wrong state
    detail: str
    saved: Path | None


@dataclasses.dataclass
class Tally:
    name: str
    out: Path
    ran: int = 0
    accepted: int = 0
    refused: int = 0
    failures: list[Failure] = dataclasses.field(default_factory=list)
    seconds: float = 0.0
    #: The pilot's wait for the screen ran out in a process the machine starved
    #: (keys campaign): no failure of the program, counted and said.
    starved: list[str] = dataclasses.field(default_factory=list)
    #: The slowest case and what it was (the locks and users campaigns).
    worst: str = ""

    def fail(self, kind: str, detail: str, data: bytes | str | None = None, suffix: str = ".txt") -> None:
        saved = None
        if data is not None:
            self.out.mkdir(parents=True, exist_ok=True)
            saved = self.out / f"{self.name}-{len(self.failures) + 1:04d}{suffix}"
            saved.write_bytes(data.encode("utf-8", "surrogateescape") if isinstance(data, str) else data)
        self.failures.append(Failure(kind, detail.strip()[-2000:], saved))

    def line(self) -> str:
        return (f"{self.name:8s} {self.ran:7d} cases  {self.accepted:6d} accepted  {self.refused:6d} refused cleanly"
                f"  {len(self.failures):4d} failures  {self.seconds:7.1f} s"
                + (f"  ({len(self.starved)} starved waits)" if self.starved else "")
                + (f"  worst case {self.worst}" if self.worst else ""))


class Hang(Exception):
    """Raised by SIGALRM in the main thread: a call did not return in time."""


@contextlib.contextmanager
def deadline(seconds: float) -> Iterator[None]:
    def ring(signum: int, frame: Any) -> None:
        raise Hang(f"no answer within {seconds:g} s")

    old = signal.signal(signal.SIGALRM, ring)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


@dataclasses.dataclass
class Outcome:
    rc: int | None
    out: str
    err: str
    error: str = ""       # a traceback or "hang: ..."


def call_main(argv: Sequence[str], timeout: float = 120.0) -> Outcome:
    """`quadtank ARGV` in this process (the same main() the console script runs)."""
    from quadtank_tui.cli import main

    out, err = io.StringIO(), io.StringIO()
    rc: int | None = None
    error = ""
    try:
        with deadline(timeout), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            rc = main(list(argv))
    except Hang as exc:
        error = f"hang: {exc}"
    except SystemExit as exc:
        rc = exc.code if isinstance(exc.code, int) else 2
    except BaseException:
        error = traceback.format_exc()
    return Outcome(rc, out.getvalue(), err.getvalue(), error)


def run_cli(argv: Sequence[str], cwd: Path, timeout: float = 120.0) -> Outcome:
    """`quadtank ARGV` as a subprocess (where the exit status itself is the point)."""
    try:
        p = subprocess.run([sys.executable, "-m", "quadtank_tui", *argv], cwd=cwd, capture_output=True,
                           text=True, errors="replace", timeout=timeout)
    except subprocess.TimeoutExpired:
        return Outcome(None, "", "", f"hang: no exit within {timeout:g} s")
    return Outcome(p.returncode, p.stdout, p.stderr)


def judge_cli(t: Tally, o: Outcome, allowed: Sequence[int], what: str, data: bytes | str | None,
              suffix: str = ".txt") -> bool:
    """One CLI outcome: a clean exit in `allowed`, an error as one line; False if it failed."""
    if o.error:
        t.fail("hang" if o.error.startswith("hang") else "traceback", f"{what}: {o.error}", data, suffix)
        return False
    if "Traceback" in o.err:
        t.fail("traceback", f"{what}: {o.err}", data, suffix)
        return False
    if o.rc not in allowed:
        t.fail("exit status", f"{what}: exit {o.rc} (expected {allowed}); stderr {o.err[-500:]!r}", data, suffix)
        return False
    if o.rc == 2:  # one error line: ours, or argparse's (after its usage lines)
        errors = [ln for ln in o.err.splitlines() if ln.startswith("quadtank") and ": error: " in ln]
        if len(errors) != 1:
            t.fail("exit status", f"{what}: exit 2 without exactly one error line: {o.err[-500:]!r}", data, suffix)
            return False
    return True


# --- mutations -----------------------------------------------------------------------------

JUNK = ["nan", "NaN", "inf", "-inf", "1e308", "-1e308", "1e999", "4.9e-324", "-4.9e-324", "0", "-0", "-1",
        "1e9", "1e10", "99999999999999999999999", "", " ", "abc", "[/x]", "[b]1", "0x10", "1_000", "1,5",
        "١٢", "１", "1e3", "1e-400", "+", "-", ".", "1..2", "∞", "\t", "%s", "${HOME}", "../x", "a/b",
        "9" * 400, "y1 y1", "t y9", "u1 u1", "Automatic", "PID", "true", "~", "null", "[]", "{}", "&a", "*a"]


def mutate_lines(text: str, rng: random.Random, extra: Sequence[str] = ()) -> str:
    """1-3 line-level mutations of `text`: values, keys, lines and bytes."""
    lines = text.split("\n")
    for _ in range(rng.randint(1, 3)):
        if not lines:
            lines = [""]
        i = rng.randrange(len(lines))
        op = rng.randrange(12)
        line = lines[i]
        if op <= 3:  # a value replaced by junk (the last word or number of the line)
            words = re.split(r"(\s+|:\s*)", line)
            idx = [n for n, w in enumerate(words) if w.strip() and not w.strip().endswith(":")]
            if idx:
                words[rng.choice(idx)] = rng.choice(JUNK)
                lines[i] = "".join(words)
        elif op == 4:
            del lines[i]
        elif op == 5:
            lines.insert(i, line)
        elif op == 6:
            j = rng.randrange(len(lines))
            lines[i], lines[j] = lines[j], lines[i]
        elif op == 7:  # a key's spelling
            lines[i] = line.swapcase() if rng.random() < 0.5 else line.replace(line.strip()[:1], "X", 1)
        elif op == 8:  # control or odd characters
            pos = rng.randrange(len(line) + 1)
            lines[i] = line[:pos] + rng.choice(["\x00", "\x1b[2J", "\r", "\ufeff", "é", "\u202e", "\t"]) + line[pos:]
        elif op == 9 and extra:
            lines.insert(i, rng.choice(extra))
        elif op == 10:  # a number pushed to an extreme
            lines[i] = re.sub(r"-?\d+(\.\d+)?", lambda m: rng.choice(["1e300", "-1e300", "0", "1e-320", "7"]), line, 1)
        else:
            lines[i] = line * rng.randint(2, 50)
    out = "\n".join(lines)
    if rng.random() < 0.05:
        out = out[: rng.randrange(len(out) + 1)]  # truncated
    if rng.random() < 0.03:
        out = "\ufeff" + out
    if rng.random() < 0.03:
        out = out.replace("\n", "\r\n")
    return out


YAML_EXTRA = [
    "- at: 1\n  set: {\"LOGGING.LogFile\": \"../../etc/x\"}",
    "- at: 0\n  set: {\"PLOTS.Upper\": \"y9\"}",
    "- at: 0\n  set: {\"LOGGING.Variables\": \"t t\"}",
    "- at: 0\n  set: {\"SAMPLING TIME.TSamp\": 50}",
    "- {at: 2, fault: {kind: leak, target: 1, value: 1e300}}",
    "- {at: 1e308, state: Run}", "- {at: .nan, state: Run}", "- {at: 1, log: on}", "- {at: 1, log: off}",
    "a: &a [1, 2]\nb: [*a, *a, *a, *a]", "[" * 300 + "]" * 300, "preset: [labjack]", "!!python/object:os.system x",
    "- at: 0\n  set: {\"CONTROLLER ONE.Ti\": 0}", "- at: 0\n  step: {\"REFERENCE ONE.Mean\": 1e308}",
    "timeout: 1e308", "timeout: .nan", "port: 70000", "host: ''", "tank_height: -1", "plausible:\n  tank1: [5, 1]",
    "calibration:\n  tank1: {gain: 0, offset: 0}", "interlock: {limit: .inf}", "outputs: {DAC0: {limits: [10, 0]}}",
]


def alias_bomb(levels: int = 9) -> str:
    lines = ['a0: &a0 ["x","x","x","x","x","x","x","x","x"]']
    lines += [f"a{i}: &a{i} [" + ",".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, levels)]
    return "\n".join(lines) + "\n"


REFUSED = object()


def read_mutant(t: Tally, data: Any, read: Callable[[Any], Any], error: type[Exception], name: str,
                suffix: str) -> Any:
    """`read(data)` judged: its result, REFUSED (a clean refusal that names the file
    `name`), or None (a failure, recorded with the input)."""
    t.ran += 1
    try:
        with deadline(30):
            return read(data)
    except error as exc:
        if name not in str(exc):
            t.fail("exit status", f"refusal does not name the file: {exc}", data, suffix)
            return None
        t.refused += 1
        return REFUSED
    except Hang as exc:
        t.fail("hang", str(exc), data, suffix)
    except Exception:
        t.fail("traceback", traceback.format_exc(), data, suffix)
    return None


# --- .par files ------------------------------------------------------------------------------

def campaign_par(t: Tally, n: int, rng: random.Random, work: Path, cli_every: int) -> None:
    from datetime import datetime

    from quadtank_tui.core.parameters import PRESET
    from quadtank_tui.files.names import check_names
    from quadtank_tui.files.par import ParFileError, format_par, parse_par

    sources = [p.read_text(encoding="ascii") for p in sorted(PARAMS.glob("*.par"))]
    extra = ["LOGGING\nLogFile ../../x", "PLOTS\nUpper y9", "SIMULATION\nOpPoint3 4.9e-324", "PLANT\nKind nope",
             "SAMPLING TIME\nTSamp 1e308", "REFERENCE ONE\nPeriod 0.01", "% TANK LOG-file", "STATE FEEDBACK\nPoles [/x]"]
    path = work / "mutant.par"
    for k in range(n):
        text = mutate_lines(rng.choice(sources), rng, extra)
        data = text.encode("utf-8", "surrogateescape")
        read = read_mutant(t, data, lambda d: parse_par(d, name="mutant.par"), ParFileError, "mutant.par", ".par")
        if read is None:
            continue
        accepted = read is not REFUSED
        if accepted:
            try:  # every value still valid: rebuild from scratch, write and read back, build the plant
                p = read.params
                again = PRESET.with_values(check_names(p.values()))
                assert again.values() == p.values(), "the values do not rebuild to themselves"
                back = parse_par(format_par(p, datetime(2000, 1, 1)), name="again.par").params
                assert back.values() == p.values(), "written and read back, the values differ"
                p.process_plant()
                assert all(math.isfinite(v) for v in p.values().values() if isinstance(v, float))
            except Exception:
                t.fail("invalid value accepted", traceback.format_exc(), data, ".par")
                continue
            t.accepted += 1
        if cli_every and k % cli_every == 0:  # the command a user types, on the same file
            path.write_bytes(data)
            o = call_main(["analyze", "--par", str(path)], timeout=60)
            judge_cli(t, o, (0, 2) if accepted else (2,), "quadtank analyze --par", data, ".par")


# --- scripts ---------------------------------------------------------------------------------

def campaign_scripts(t: Tally, n: int, rng: random.Random, work: Path) -> None:
    from quadtank_tui.files.script import ScriptError, parse_script

    sources = [p.read_text() for p in sorted(PARAMS.glob("*.yaml")) if _is_script(p)]
    path = work / "mutant.yaml"
    for k in range(n):
        text = alias_bomb() if rng.random() < 0.01 else mutate_lines(rng.choice(sources), rng, YAML_EXTRA)
        script = read_mutant(t, text, lambda d: parse_script(d, name="mutant.yaml"), ScriptError, "mutant.yaml",
                             ".yaml")
        if script is None:
            continue
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
        if script is REFUSED:
            o = call_main(["run", "--script", str(path), "--duration", "1", "--log", str(work / "s.log")], 60)
            judge_cli(t, o, (2,), "quadtank run --script (refused)", text, ".yaml")
            continue
        t.accepted += 1
        log = work / f"s{k}.log"
        duration = min(120.0, max((e.at for e in script.events), default=0.0) + 10.0)
        o = call_main(["run", "--par", "minphase", "--script", str(path), "--duration", f"{duration:g}",
                       "--log", str(log)], timeout=120)
        if judge_cli(t, o, (0, 1, 2), "quadtank run --script (accepted)", text, ".yaml") and o.rc == 0:
            if not log.exists() and "no log written" not in o.out + o.err:
                t.fail("lost row", f"exit 0 but no {log.name} and no word of it: {o.out[-400:]}", text, ".yaml")
        for f in work.glob("s*.log*"):
            f.unlink()


def _is_script(path: Path) -> bool:
    return path.read_text().lstrip("# \n").startswith("-") or "\n- at:" in path.read_text()


# --- DAQ configurations ----------------------------------------------------------------------

def campaign_daq(t: Tally, n: int, rng: random.Random, work: Path) -> None:
    from quadtank_tui.daq.config import DaqConfigError, parse_daq_config

    sources = [p.read_text() for p in sorted(PARAMS.glob("*.yaml")) if not _is_script(p)]
    path = work / "mutant-daq.yaml"
    for _ in range(n):
        r = rng.random()
        text = (alias_bomb() if r < 0.02 else "host: " + "[" * 500 + "]" * 500 + "\n" if r < 0.04
                else mutate_lines(rng.choice(sources), rng, YAML_EXTRA))
        cfg = read_mutant(t, text, lambda d: parse_daq_config(d, name="mutant-daq.yaml"), DaqConfigError,
                          "mutant-daq.yaml", ".yaml")
        if cfg is None:
            continue
        if cfg is REFUSED:
            path.write_text(text, encoding="utf-8", errors="surrogateescape")
            o = call_main(["daq", "check", str(path)], timeout=60)
            judge_cli(t, o, (2,), "quadtank daq check (refused)", text, ".yaml")
            continue
        try:
            _check_config(cfg)
        except Exception:
            t.fail("invalid value accepted", traceback.format_exc(), text, ".yaml")
            continue
        t.accepted += 1


def _check_config(cfg: Any) -> None:
    """What an accepted configuration must be for the backend to use it safely."""
    assert 1 <= cfg.port <= 65535 and 0 <= cfg.device_id <= 255, (cfg.port, cfg.device_id)
    assert math.isfinite(cfg.timeout) and 0 < cfg.timeout <= 60, cfg.timeout
    assert math.isfinite(cfg.tank_height) and cfg.tank_height > 0, cfg.tank_height
    assert math.isfinite(cfg.interlock_limit) and math.isfinite(cfg.sensor_gain) and cfg.sensor_gain > 0
    for tank in range(1, 5):
        lo, hi = cfg.plausible_range(tank)
        assert math.isfinite(lo) and math.isfinite(hi) and lo < hi, (tank, lo, hi)
        cfg.tank_register(tank)
    for s in (*cfg.sensors, *cfg.pumps):
        for v in dataclasses.asdict(s).values():
            assert not isinstance(v, float) or math.isfinite(v), s
    for pump in (1, 2):
        lo, hi = cfg.pump_output(pump).limits
        assert math.isfinite(lo) and math.isfinite(hi) and lo < hi, (pump, lo, hi)


# --- the TUI: random keys and bad values in every field --------------------------------------

KEYS = (list("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789")
        + ["enter", "escape", "tab", "shift+tab", "up", "down", "left", "right", "pageup", "pagedown", "home",
           "end", "backspace", "delete", "space", "f1", "question_mark", "plus", "minus", "left_square_bracket",
           "right_square_bracket", "left_curly_bracket", "right_curly_bracket", "full_stop", "comma", "slash",
           "ctrl+a", "ctrl+k", "ctrl+e", "ctrl+p", "ctrl+q", "ctrl+c", "ctrl+z"])
#: Window openers (keys from Main), then the Setup screen's.
WINDOWS = [("1",), ("4",), ("i",), ("I",), ("h",), ("v",), ("l",), ("F",), ("g",),
           ("S", "s"), ("S", "i"), ("S", "1"), ("S", "f"), ("S", "h", "enter")]


def _engine(folder: Path) -> Any:
    from quadtank_tui.engine.runner import build_engine
    from quadtank_tui.files.shipped import write_shipped

    (folder / "logs").mkdir(parents=True, exist_ok=True)
    write_shipped(folder / "params")
    return build_engine(clock="manual", seed=1, params_dir=folder / "params", logs_dir=folder / "logs")


def _valid(params: Any) -> str:
    """'' if `params` is a valid parameter set, else why not."""
    from quadtank_tui.core.parameters import PRESET
    from quadtank_tui.files.names import check_names

    try:
        again = PRESET.with_values(check_names(params.values()))
        assert again.values() == params.values()
        params.process_plant()
        return ""
    except Exception as exc:
        return f"{type(exc).__name__}: {exc}"


async def _burst(pilot: Any, keys: Sequence[str], starved: list[str]) -> None:
    """Keys as they arrive over SSH: all queued before the app handles the first
    (the pilot tests' helper, tests/ui/bursts.py).  If the pilot's wait for the
    screen runs out (WaitForScreenTimeout, 30 s), what it was is found out: a wait
    that ends in a process the machine starved is noted in `starved` and the
    session goes on; one in which the app computed, or that never ends, fails."""
    from textual.pilot import WaitForScreenTimeout

    if str(ROOT / "tests" / "ui") not in sys.path:
        sys.path.insert(0, str(ROOT / "tests" / "ui"))
    from bursts import burst

    while pilot.app.is_running:
        wall, cpu = time.monotonic(), time.process_time()
        try:
            await burst(pilot, *keys)
            return
        except WaitForScreenTimeout:
            starved.append(await _why_timed_out(pilot, wall, cpu))
            keys = ()  # sent: wait for the rest of them to be handled


class ScreenHang(Exception):
    """The screen never handled what was posted to it: a real hang."""


class ScreenBusy(Exception):
    """The screen took over 30 s to handle its messages and the process computed
    most of that time: the program, not the machine."""


async def _why_timed_out(pilot: Any, wall: float, cpu: float, more: float = 120.0) -> str:
    """After a WaitForScreenTimeout: wait up to `more` seconds for the screen to
    become idle, and tell a starved process (it got little CPU: the machine's
    load) from a busy one (ScreenBusy) and from a hang (ScreenHang), naming the
    widgets that held messages when the wait ran out."""
    from textual.pilot import WaitForScreenTimeout

    app = pilot.app
    try:
        nodes = [app, *app.screen.walk_children(with_self=True)]
    except Exception:  # no screen: the app is closing
        nodes = [app]
    holding = ", ".join(f"{type(n).__name__}#{n.id or ''} ({n._message_queue.qsize()})" for n in nodes
                        if not n._message_queue.empty()) or "none"
    idle = False
    deadline = time.monotonic() + more
    while not idle and time.monotonic() < deadline and app.is_running:
        try:
            idle = await pilot._wait_for_screen(timeout=10.0)
        except WaitForScreenTimeout:
            pass
    took, used = time.monotonic() - wall, time.process_time() - cpu
    said = f"holding messages: {holding}; {took:.0f} s of wall time, {used:.1f} s of CPU"
    if not idle and app.is_running:
        raise ScreenHang(f"the screen never became idle; {said}")
    if used > 0.5 * took:
        raise ScreenBusy(f"the app computed through the wait; {said}")
    return f"starved: idle again; {said}"


#: Trail lines that are no burst of keys: the engine run on for that many seconds;
#: the terminal resized (columns x rows).
RUN_FOR = "!run_for "
RESIZE = "!size "
#: Terminal sizes a session moves between: the 80x24 minimum, below it (the
#: "too small" sentence), and larger.
SIZES = ((120, 40), (120, 40), (100, 30), (80, 24), (70, 20))
Step = list[str] | float | tuple[int, int]


async def _session(app: Any, engine: Any, bursts: Iterator[Step], trail: list[str], starved: list[str]) -> None:
    """One app session: each burst of keys pressed at once, each float the engine
    run on for that long, each pair a new terminal size; every step written to
    `trail` (one line each) first, so a
    failing session's trail replays it (`--replay`).  Notifications shown, as a
    terminal shows them (the pilot hides them by default, and a toast's text is
    read as markup only when it renders)."""
    async with _app_running(app) as pilot:
        for step in bursts:
            if not app.is_running:
                break
            if isinstance(step, float):
                trail.append(f"{RUN_FOR}{step:g}")
                engine.run_for(step)
            elif isinstance(step, tuple):
                trail.append(f"{RESIZE}{step[0]}x{step[1]}")
                await asyncio.wait_for(pilot.resize_terminal(*step), timeout=60)
                await asyncio.wait_for(_burst(pilot, [], starved), timeout=300)
            else:
                trail.append(" ".join(step))
                await asyncio.wait_for(_burst(pilot, step, starved), timeout=300)
            if app.is_running and (wrong := _screen_problem(app)):
                raise WrongState(wrong)


@contextlib.asynccontextmanager
async def _app_running(app: Any, close_within: float = 60.0) -> AsyncIterator[Any]:
    """`app.run_test()` at 120x40 with notifications shown, except that an app
    that does not close within `close_within` seconds (its loop hangs: the
    failure is already recorded) is left behind instead of hanging the campaign."""
    test = app.run_test(size=(120, 40), notifications=True)
    pilot = await test.__aenter__()
    try:
        yield pilot
    except BaseException as exc:
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(close_within):  # in this task: run_test resets its context here
                await test.__aexit__(type(exc), exc, exc.__traceback__)
        raise
    try:
        async with asyncio.timeout(close_within):
            await test.__aexit__(None, None, None)
    except TimeoutError:
        raise ScreenHang(f"the app did not close within {close_within:g} s") from None


class WrongState(Exception):
    """The screens left in a state no key sequence should leave them in."""


def _screen_problem(app: Any) -> str:
    """'' if the screen stack is one a user can be in once the keys are handled;
    else what is wrong with it."""
    from textual.command import CommandPalette

    from quadtank_tui.ui.screens.help import HelpScreen
    from quadtank_tui.ui.screens.too_small import TooSmallScreen, too_small

    stack = app.screen_stack
    names = [type(s).__name__ for s in stack]
    if app.main not in stack:
        return f"no Main screen in {names}"
    if len(stack) > 8 or len({id(s) for s in stack}) != len(stack):
        return f"screens piled up: {names}"
    # Help, the palette over it, Help again (F1 there) is allowed; no more.
    if sum(isinstance(s, CommandPalette) for s in stack) > 1 or sum(isinstance(s, HelpScreen) for s in stack) > 2:
        return f"palette or help piled up: {names}"
    if sum(isinstance(s, TooSmallScreen) for s in stack) > 1:
        return f"'terminal too small' twice: {names}"
    if isinstance(app.screen, TooSmallScreen) and not too_small(*app.size):
        return f"'terminal too small' on a {app.size[0]}x{app.size[1]} terminal: {names}"
    return ""


async def _judged(t: Tally, engine: Any, trail: list[str], session: Any) -> None:
    """Await a session and judge it: a hang, a traceback, or the values it left."""
    try:
        await session
    except asyncio.TimeoutError:
        t.fail("hang", f"a burst took over 300 s (after {len(trail)} bursts)", "\n".join(trail))
        return
    except ScreenHang as exc:
        t.fail("hang", f"after {len(trail)} bursts: {exc}", "\n".join(trail))
        return
    except ScreenBusy as exc:
        t.fail("slow", f"after {len(trail)} bursts: {exc}", "\n".join(trail))
        return
    except WrongState as exc:
        t.fail("wrong state", f"after {len(trail)} bursts: {exc}", "\n".join(trail))
        return
    except Exception:
        t.fail("traceback", traceback.format_exc(), "\n".join(trail))
        return
    finally:
        engine.stop()
    why = _valid(engine.snapshot().params)
    if why:
        t.fail("invalid value accepted", why, "\n".join(trail))
    else:
        t.accepted += 1  # a session that ended cleanly


async def _keys(t: Tally, n: int, rng: random.Random, work: Path) -> None:
    from quadtank_tui.ui.app import build_app

    left = n
    session = 0
    start = time.monotonic()

    def bursts(app: Any) -> Iterator[Step]:
        nonlocal left
        pressed = 0
        while left > 0 and app.is_running and pressed < 1500:
            chunk = [rng.choice(KEYS) for _ in range(min(left, rng.randint(1, 12)))]
            pressed += len(chunk)
            left -= len(chunk)
            t.ran += len(chunk)
            yield chunk
            if rng.random() < 0.05:
                yield rng.choice((0.1, 1.0, 10.0))
            if rng.random() < 0.03:
                yield rng.choice(SIZES)

    while left > 0:
        session += 1
        engine = _engine(work / f"keys{session}")
        app = build_app(engine, refresh_interval=0.05, wall_clock=lambda: 0.0)
        trail: list[str] = []
        failed = len(t.failures)
        await _judged(t, engine, trail, _session(app, engine, bursts(app), trail, t.starved))
        print(f"  keys: session {session}, {t.ran}/{n} keys, {time.monotonic() - start:.0f} s"
              + (f", FAILED: {t.failures[-1].kind}" if len(t.failures) > failed else ""),
              file=sys.stderr, flush=True)


def _steps(lines: Sequence[str]) -> list[Step]:
    """A trail's lines as steps: a burst of keys a line, `!run_for S`, `!size WxH`."""
    steps: list[Step] = []
    for line in lines:
        if line.startswith(RUN_FOR):
            steps.append(float(line[len(RUN_FOR):]))
        elif line.startswith(RESIZE):
            w, h = line[len(RESIZE):].split("x")
            steps.append((int(w), int(h)))
        elif line.strip():
            steps.append(line.split())
    return steps


def replay_keys(lines: Sequence[str], work: Path, out: Path) -> Tally:
    """A saved trail of the keys campaign replayed on a fresh app and engine,
    judged as the campaign judges it."""
    from quadtank_tui.ui.app import build_app

    steps = _steps(lines)
    t = Tally("replay", out)
    t.ran = sum(len(s) for s in steps if isinstance(s, list))
    start = time.monotonic()
    engine = _engine(Path(tempfile.mkdtemp(prefix="replay-", dir=work)))
    app = build_app(engine, refresh_interval=0.05, wall_clock=lambda: 0.0)
    trail: list[str] = []
    asyncio.run(_judged(t, engine, trail, _session(app, engine, iter(steps), trail, t.starved)))
    t.seconds = time.monotonic() - start
    return t


def _signature(t: Tally) -> str | None:
    """What a replay's first failure was, without its numbers (None: it passed)."""
    if not t.failures:
        return None
    f = t.failures[0]
    last = f.detail.splitlines()[-1] if f.detail else ""
    return f"{f.kind}: " + re.sub(r"\d+", "N", re.sub(r"^after \d+ bursts: ", "", last))[:120]


def shrink_keys(lines: list[str], work: Path) -> tuple[list[str], str | None]:
    """The shortest trail found that fails as `lines` fails: whole lines dropped
    (halves, quarters, ... one at a time), then single keys.  A failure that
    depends on timing may not come back each time: what is kept always failed."""
    def fails(candidate: list[str]) -> bool:
        return _signature(replay_keys(candidate, work, work)) == want

    want = _signature(replay_keys(lines, work, work))
    if want is None:
        return lines, None
    parts = 2
    while len(lines) > 1:
        size = -(-len(lines) // parts)
        for i in range(0, len(lines), size):
            if fails(candidate := lines[:i] + lines[i + size:]):
                lines, parts = candidate, max(2, parts - 1)
                break
        else:
            if size == 1:
                break
            parts = min(len(lines), 2 * parts)
    for i in range(len(lines)):
        if lines[i].startswith("!"):
            continue
        for j in reversed(range(len(lines[i].split()))):
            keys = lines[i].split()
            if len(keys) > 1 and fails(candidate := [*lines[:i], " ".join(keys[:j] + keys[j + 1:]), *lines[i + 1:]]):
                lines = candidate
    return lines, want


FIELD_VALUES = [v for v in JUNK if v.strip()] + ["x" * 300, "[/x]" * 3, "-1e-300", "0.00000001", "100000"]


async def _fields(t: Tally, n: int, rng: random.Random, work: Path) -> None:
    from textual.widgets import Input

    from quadtank_tui.ui.app import build_app

    engine = _engine(work / "fields")
    app = build_app(engine, refresh_interval=0.05, wall_clock=lambda: 0.0)
    done = 0
    trail: list[str] = []
    try:
        async with app.run_test(size=(120, 40), notifications=True) as pilot:
            while done < n:
                for opener in WINDOWS:
                    for key in opener:
                        await pilot.press(key)
                    inputs = [w for w in app.screen.query(Input) if not w.disabled]
                    for k in range(len(inputs)):
                        if done >= n:
                            break
                        fields = [w for w in app.screen.query(Input) if not w.disabled]
                        if k >= len(fields):
                            break
                        value = rng.choice(FIELD_VALUES)
                        trail.append(f"{'+'.join(opener)} field {k} ({fields[k].id}): {value!r}")
                        fields[k].value = ""
                        fields[k].focus()
                        await pilot.pause()
                        before = engine.snapshot().params
                        if len(value) > 24:  # the start set at once, the last characters typed
                            fields[k].value = value[:-24]
                        for ch in value[-24:]:  # typed, as a user would (a key each)
                            if ch.isprintable():
                                await pilot.press("space" if ch == " " else ch)
                        await pilot.press("enter")
                        done += 1
                        t.ran += 1
                        after = engine.snapshot().params
                        why = _valid(after)
                        if why:
                            t.fail("invalid value accepted", f"{trail[-1]}: {why}", "\n".join(trail))
                        elif after != before:
                            t.accepted += 1
                        else:
                            t.refused += 1
                        if not app.is_running:
                            raise RuntimeError("the app ended on a typed value")
                        if app.screen is app.main and k + 1 < len(inputs):
                            for key in opener:  # Enter set the values and closed it: open it again
                                await pilot.press(key)
                    for _ in range(3):  # back to Main
                        if app.screen is app.main:
                            break
                        await pilot.press("escape")
                    if app.screen is not app.main and hasattr(app, "main"):
                        await pilot.press("escape")
                    if done >= n:
                        break
    except Exception:
        t.fail("traceback", traceback.format_exc(), "\n".join(trail))
    finally:
        engine.stop()


def campaign_keys(t: Tally, n: int, rng: random.Random, work: Path) -> None:
    asyncio.run(_keys(t, n, rng, work))


def campaign_fields(t: Tally, n: int, rng: random.Random, work: Path) -> None:
    asyncio.run(_fields(t, n, rng, work))


# --- SIGKILL while logging -------------------------------------------------------------------

def campaign_kills(t: Tally, n: int, rng: random.Random, work: Path) -> None:
    from quadtank_tui.files.log_reader import read_log

    par = work / "t.par"
    par.write_text("LOGGING\nVariables t y1 y2 u1 u2\nPoints 100000\n")
    for k in range(n):
        folder = work / f"kill{k}"
        folder.mkdir()
        log = folder / "k.log"
        proc = subprocess.Popen([sys.executable, "-m", "quadtank_tui", "run", "--par", str(par), "--duration",
                                 "100000", "--speed", "50", "--log", str(log)], cwd=folder,
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        partial = folder / "k.log.partial"
        start = time.monotonic()
        while not partial.exists() and time.monotonic() - start < 60 and proc.poll() is None:
            time.sleep(0.05)
        time.sleep(rng.uniform(0.2, 3.0))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        t.ran += 1
        if not partial.exists():
            t.fail("lost row", f"kill {k}: no {partial.name} (stderr {proc.stderr.read()[-300:]!r})")  # type: ignore[union-attr]
            continue
        try:
            data = read_log(partial)
            tcol = data["t"]
            rows = data.rows
            steps = [round(b - a, 6) for a, b in zip(tcol, tcol[1:])]
            assert rows > 0 and abs(tcol[0]) < 1e-9 and all(s == 0.1 for s in steps), "rows missing or out of order"
            assert not data.warnings, data.warnings
        except Exception:
            t.fail("lost row", f"kill {k}: {traceback.format_exc()}", partial.read_bytes(), ".log")
            continue
        o = call_main(["run", "--par", str(par), "--duration", "1", "--log", str(log)], timeout=60)
        recovered = folder / "k-recovered.log"
        if judge_cli(t, o, (0,), f"kill {k}: the next run", None):
            if not recovered.exists() or read_log(recovered).rows != rows:
                t.fail("lost row", f"kill {k}: {rows} rows in the partial log; recovered: "
                       f"{read_log(recovered).rows if recovered.exists() else 'none'}; {o.out[-300:]}")
                continue
            t.accepted += 1


# --- Modbus devices that misbehave -----------------------------------------------------------

class Rig:
    """`quadtank rig` on a free loopback port."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "quadtank_tui", "rig", "--port", "0", "--map",
                                      str(PARAMS / "virtual-rig.yaml"), *args],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if "serving on" not in line:
            raise RuntimeError(f"rig did not start: {line!r}")
        self.port = int(line.split("serving on ")[1].split()[0].rsplit(":", 1)[1])
        threading.Thread(target=self.proc.stdout.read, daemon=True).start()

    def dacs(self) -> tuple[float, float]:
        from pymodbus.client import ModbusTcpClient

        from quadtank_tui.daq.registers import decode
        from quadtank_tui.daq.config import load_daq_config

        dac = load_daq_config(PARAMS / "virtual-rig.yaml").pump_output(1).register
        client = ModbusTcpClient("127.0.0.1", port=self.port, timeout=2.0)
        try:
            rr = client.read_holding_registers(1000, count=4, device_id=1)
            return decode(dac, rr.registers[:2]), decode(dac, rr.registers[2:])
        finally:
            client.close()

    def stop(self) -> None:
        with contextlib.suppress(ProcessLookupError):
            self.proc.send_signal(signal.SIGCONT)
        self.proc.kill()
        self.proc.wait()


class SilentDevice:
    """Accepts connections and never answers (a hung device)."""

    def __init__(self) -> None:
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen()
        self.port = self.sock.getsockname()[1]
        self.held: list[socket.socket] = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        with contextlib.suppress(OSError):
            while True:
                self.held.append(self.sock.accept()[0])

    def stop(self) -> None:
        for c in self.held:
            c.close()
        self.sock.close()


def _pumps_cut(rig: Rig) -> None:
    """Mid-run: the interlock holds both pumps at 0 (raises if not)."""
    time.sleep(1.0)
    dacs = rig.dacs()
    if dacs != (0.0, 0.0):
        raise AssertionError(f"every tank reads above the interlock limit, yet the pumps are at {dacs} V")


def _daq_config(work: Path, port: int, timeout: float) -> Path:
    text = (PARAMS / "virtual-rig.yaml").read_text()
    text = text.replace("port: 5020", f"port: {port}").replace("timeout: 0.2", f"timeout: {timeout}")
    path = work / f"rig-{port}.yaml"
    path.write_text(text)
    return path


def campaign_devices(t: Tally, work: Path) -> None:
    """Each misbehaviour once: the run ends on time, with the right status and the pumps at 0."""
    def case(name: str, rig_args: Sequence[str] | None, timeout: float, duration: float, expect: int,
             during: Callable[[Any], None] | None, words: str, bound: float) -> None:
        t.ran += 1
        device: Any = Rig(*rig_args) if rig_args is not None else SilentDevice()
        try:
            cfg = _daq_config(work, device.port, timeout)
            log = work / f"{name}.log"
            proc = subprocess.Popen([sys.executable, "-m", "quadtank_tui", "run", "--daq", str(cfg), "--realtime",
                                     "--duration", str(duration), "--log", str(log), "--par",
                                     str(PARAMS / "default.par")], cwd=work, stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, text=True)
            t0 = time.monotonic()
            if during is not None:
                time.sleep(min(2.0, duration / 2))
                during(device)
            try:
                out, err = proc.communicate(timeout=bound + 60)
            except subprocess.TimeoutExpired:
                proc.kill()
                t.fail("hang", f"{name}: run --daq did not end within {bound + 60:g} s")
                return
            took = time.monotonic() - t0
            o = Outcome(proc.returncode, out, err)
            if not judge_cli(t, o, (expect,), f"{name} device", None):
                return
            if words not in out + err:
                t.fail("exit status", f"{name}: {words!r} not said; stdout {out[-400:]!r} stderr {err[-300:]!r}")
                return
            if took > bound:
                t.fail("hang", f"{name}: the {duration:g} s run took {took:.1f} s (bound {bound:g} s)")
                return
            if isinstance(device, Rig) and device.proc.poll() is None:
                device.proc.send_signal(signal.SIGCONT)
                time.sleep(0.5)
                dacs = device.dacs()
                if dacs != (0.0, 0.0):
                    t.fail("exit status", f"{name}: the pumps were left at {dacs} V")
                    return
            t.accepted += 1
        except Exception:
            t.fail("traceback", f"{name}: {traceback.format_exc()}")
        finally:
            device.stop()

    case("killed", [], 0.2, 8, 1, lambda d: d.proc.kill(), "FAULT", 30)
    case("frozen", ["--watchdog", "1"], 0.2, 8, 1, lambda d: d.proc.send_signal(signal.SIGSTOP), "FAULT", 30)
    case("slow", ["--reply-delay", "0.15"], 1.0, 3, 0, None, "log", 20)
    case("hung", None, 0.2, 5, 1, None, "no answer within 0.2 s", 30)
    case("lying-low", ["--offset", "-10.5"], 0.2, 3, 1, None, "sensor fault", 20)  # a broken wire
    # +1e30 V clamps at the converter's +10.5 V rail: 21 cm, plausible but above the
    # interlock's 19 cm, so the pumps must be cut while the run goes on.
    case("lying-high", ["--offset", "1e30"], 0.2, 6, 0, _pumps_cut, "log", 20)


def campaign_hosts(t: Tally, n: int, rng: random.Random, work: Path) -> None:
    """`quadtank run --daq` at TSamp 0.1 s (watchdog timeout 1 s) killed or stopped
    while its pumps run at 3 V.  SIGKILL: the pumps must be at 0 within the timeout
    plus a sample (the guard; on the map without a watchdog nothing else could);
    SIGSTOP: likewise (the device's watchdog, or the guard), and after SIGCONT the
    run must pause (FAULT, exit 1) with the pumps left at 0.  Prints the worst times.
    Without a watchdog a stop is the guard's to notice (it looks every 0.05 s and
    acts once the stop outlasts the timeout): 0.15 s more is allowed there."""
    within = 1.1
    worst: dict[str, float] = {}
    bare = work / "bare-map.yaml"
    bare.write_text((PARAMS / "virtual-rig.yaml").read_text() + "watchdog: none\n")
    for k in range(n):
        how = ("kill", "stop")[k % 2]
        map_kind = ("watchdog", "none")[(k // 2) % 2]
        name = f"{how}-{map_kind}-{k}"
        t.ran += 1
        rig = Rig(*(["--map", str(bare)] if map_kind == "none" else []))
        try:
            cfg = _daq_config(work, rig.port, 5.0)
            if map_kind == "none":
                cfg.write_text(cfg.read_text() + "watchdog: none\n")
            proc = subprocess.Popen([sys.executable, "-m", "quadtank_tui", "run", "--daq", str(cfg), "--duration",
                                     "14" if how == "stop" else "600", "--log", str(work / f"{name}.log")],
                                    cwd=work, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            start = time.monotonic()
            while min(rig.dacs()) < 2.9 and proc.poll() is None and time.monotonic() - start < 60:
                time.sleep(0.05)
            time.sleep(rng.uniform(0.0, 1.0))
            proc.send_signal(signal.SIGKILL if how == "kill" else signal.SIGSTOP)
            t0 = time.monotonic()
            bound = within + (0.15 if how == "stop" and map_kind == "none" else 0.0)
            if how == "kill" or map_kind == "none":  # nobody else talks to the rig: poll it
                while rig.dacs() != (0.0, 0.0) and time.monotonic() - t0 < 30:
                    time.sleep(0.02)
                took = time.monotonic() - t0
            else:  # a read would clear the watchdog's timer: look once, after the timeout and a sample
                time.sleep(within)
                took = within
            dacs = rig.dacs()
            worst[f"{how}, {map_kind}"] = max(worst.get(f"{how}, {map_kind}", 0.0), took)
            if dacs != (0.0, 0.0) or took > bound:
                t.fail("wrong state", f"{name}: pumps at {dacs} V {took:.2f} s after SIG{how.upper()}")
            if how == "stop":
                time.sleep(rng.uniform(0.5, 2.0))
                proc.send_signal(signal.SIGCONT)
            out, err = proc.communicate(timeout=60)
            if how == "stop" and (proc.returncode != 1 or "no request reached the rig" not in out):
                t.fail("exit status", f"{name}: after SIGCONT exit {proc.returncode}, stdout {out[-400:]!r}")
            elif how == "kill" and "quadtank guard:" not in err:
                t.fail("exit status", f"{name}: the guard said nothing; stderr {err[-300:]!r}")
            elif rig.dacs() != (0.0, 0.0):
                t.fail("wrong state", f"{name}: the pumps went back to {rig.dacs()} V")
            else:
                t.accepted += 1
        except Exception:
            t.fail("traceback", f"{name}: {traceback.format_exc()}")
        finally:
            rig.stop()
    for what, took in sorted(worst.items()):
        print(f"    {what}: worst {took:.2f} s to 0 V" + (" (looked once, at the bound)" if what == "stop, watchdog"
                                                          else ""))


# --- hostile path names ----------------------------------------------------------------------

def hostile_paths(work: Path) -> list[str]:
    fifo = work / "fifo"
    if not fifo.exists():
        os.mkfifo(fifo)
    (work / "adir").mkdir(exist_ok=True)
    loop = work / "loop"
    if not loop.is_symlink():
        os.symlink(loop, loop)
    return ["", " ", "-", "--", "-h", "x" * 300, "a/" * 2100 + "x", "no/such/dir/x.log", "/dev/zero", "/dev/null",
            "/dev/full", "/proc/self/mem", str(fifo), str(work / "adir"), str(loop), "x\ny", "x\x1b[31mred",
            "日本語.log", "[/x].log", "%s%n", "~/x", "$HOME/x", ".", "..", "/", "x.log/", "a b.log",
            os.fsdecode(b"\xff\xfe.log"), "../escape.log", "params/default.par"]


def campaign_paths(t: Tally, work: Path) -> None:
    good_log = work / "good.log"
    call_main(["run", "--duration", "2", "--log", str(good_log)])
    writers = [
        lambda p: ["run", "--duration", "1", "--log", p],
        lambda p: ["log", "export", str(good_log), "--to", "csv", "--out", p],
    ]
    readers = [
        lambda p: ["run", "--duration", "1", "--log", str(work / "o.log"), "--par", p],
        lambda p: ["run", "--duration", "1", "--log", str(work / "o.log"), "--script", p],
        lambda p: ["log", "info", p],
        lambda p: ["daq", "check", p],
        lambda p: ["analyze", "--par", p],
        lambda p: ["design", "--par", p, "--no-step"],
        lambda p: ["icad", "--par", p],
    ]
    cwd = Path.cwd()
    os.chdir(work)
    try:
        for p in hostile_paths(work):
            # a file is written only inside the work folder (never /dev/zero.log and the like)
            outside = p.startswith("/") and not p.startswith(str(work))
            for make in readers if outside else [*writers, *readers]:
                argv = make(p)
                t.ran += 1
                o = call_main(argv, timeout=60)
                if judge_cli(t, o, (0, 2), " ".join(argv)[:200], repr(argv)):
                    if o.rc == 0:
                        t.accepted += 1
                    else:
                        t.refused += 1
    finally:
        os.chdir(cwd)
    if (ROOT / "escape.log").exists() or Path("/escape.log").exists():
        t.fail("invalid value accepted", "a log was written outside the work folder")


def campaign_lock_users(t: Tally, name: str, work: Path, rounds: int = 10) -> None:
    """benchmarks/hardening_locks.py's campaign `name`, counted in this table."""
    from hardening_locks import CAMPAIGNS as LOCK_CAMPAIGNS, Campaign

    c = Campaign(name)
    LOCK_CAMPAIGNS[name](c, rounds, work)
    t.ran, t.accepted = c.runs, c.runs - len(c.failures)
    for failure in c.failures:
        t.fail("wrong state", failure)
    t.worst = f"{c.worst[0]:.2f} s ({c.worst[1]})" if c.runs else ""


# --- main ------------------------------------------------------------------------------------

def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--seed", type=int, default=18)
    p.add_argument("--issue", action="store_true", help="the issue's counts: " + ", ".join(
        f"{k} {v}" for k, v in ISSUE_COUNTS.items()))
    for name in ISSUE_COUNTS:
        p.add_argument(f"--{name}", type=int, metavar="N", help=f"cases (default {SMALL_COUNTS[name]})")
    p.add_argument("--only", help="comma-separated campaigns: " + ",".join(CAMPAIGNS))
    p.add_argument("--cli-every", type=int, default=10, metavar="K",
                   help="also run `quadtank analyze --par` on every K-th .par mutant (0: never)")
    p.add_argument("--out", help="folder for the failing inputs (default: a new temporary folder)")
    p.add_argument("--replay", metavar="FILE", help="replay a failing session of the keys campaign (its saved "
                   "keys-NNNN.txt: a burst a line) and print what became of it")
    p.add_argument("--shrink", action="store_true", help="with --replay: cut the trail down to the fewest lines "
                   "and keys that still fail the same way (tens of replays: minutes)")
    return p.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    counts = dict(ISSUE_COUNTS if args.issue else SMALL_COUNTS)
    counts.update({k: getattr(args, k) for k in ISSUE_COUNTS if getattr(args, k) is not None})
    chosen = args.only.split(",") if args.only else list(CAMPAIGNS)
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="hardening-"))
    out.mkdir(parents=True, exist_ok=True)
    work_root = Path(tempfile.mkdtemp(prefix="hardening-work-"))
    os.environ.setdefault("NO_COLOR", "1")
    if args.replay and args.shrink:
        lines, why = shrink_keys(Path(args.replay).read_text().splitlines(), work_root)
        shutil.rmtree(work_root, ignore_errors=True)
        if why is None:
            print("the trail did not fail again: nothing to shrink")
            return 0
        (out / "shrunk.txt").write_text("\n".join(lines) + "\n")
        print(f"{why}\n{sum(len(s) for s in _steps(lines) if isinstance(s, list))} keys, "
              f"saved as {out / 'shrunk.txt'}:\n" + "\n".join(lines))
        return 1
    if args.replay:
        t = replay_keys(Path(args.replay).read_text().splitlines(), work_root, out)
        shutil.rmtree(work_root, ignore_errors=True)
        print(t.line())
        for f in t.failures:
            print(f"    {f.kind}: {f.detail}")
        for note in t.starved:
            print(f"    {note}")
        return 1 if t.failures else 0
    tallies = []
    for name in chosen:
        rng = random.Random(f"{args.seed}-{name}")
        work = work_root / name
        work.mkdir()
        shutil.copytree(PARAMS, work / "params")
        t = Tally(name, out)
        start = time.monotonic()
        cwd = Path.cwd()
        os.chdir(work)
        try:
            if name == "par":
                campaign_par(t, counts["par"], rng, work, args.cli_every)
            elif name == "scripts":
                campaign_scripts(t, counts["scripts"], rng, work)
            elif name == "daq":
                campaign_daq(t, counts["daq"], rng, work)
            elif name == "keys":
                campaign_keys(t, counts["keys"], rng, work)
            elif name == "fields":
                campaign_fields(t, counts["fields"], rng, work)
            elif name == "kills":
                campaign_kills(t, counts["kills"], rng, work)
            elif name == "devices":
                campaign_devices(t, work)
            elif name == "hosts":
                campaign_hosts(t, counts["hosts"], rng, work)
            elif name == "paths":
                campaign_paths(t, work)
            elif name in ("locks", "users"):
                campaign_lock_users(t, name, work)
            elif name == "sockets":
                from socket_campaign import campaign_sockets  # benchmarks/ is on the path of this script

                campaign_sockets(t, counts["sockets"], rng, work)
            else:
                raise SystemExit(f"unknown campaign {name!r}; choose from {', '.join(CAMPAIGNS)}")
        finally:
            os.chdir(cwd)
        t.seconds = time.monotonic() - start
        tallies.append(t)
        print(t.line(), flush=True)
        for f in t.failures[:20]:
            print(f"    {f.kind}: {f.detail.splitlines()[-1] if f.detail else ''}"
                  + (f"  [{f.saved}]" if f.saved else ""), flush=True)
        if len(t.failures) > 20:
            print(f"    ... {len(t.failures) - 20} more under {out}", flush=True)
        for note in t.starved:
            print(f"    {note}", flush=True)
    shutil.rmtree(work_root, ignore_errors=True)
    total = sum(len(t.failures) for t in tallies)
    print(f"seed {args.seed}: {sum(t.ran for t in tallies)} cases, {total} failures, "
          f"{sum(t.seconds for t in tallies):.0f} s; failing inputs under {out}")
    return 1 if total else 0


if __name__ == "__main__":
    sys.exit(main())
