"""`quadtank run`: build an engine without a UI, run a script, save the log, summarize.

Kept apart from the CLI's argument parsing so the tests drive it directly.  Virtual
runs stamp their log with :func:`virtual_epoch` plus process time, so a given `.par`,
script and seed give the same bytes every time.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from quadtank_tui.core.parameters import ControlMode
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.engine.backend import ProcessBackend
from quadtank_tui.engine.commands import CommandResult, LogOn, SetOperation, SetParams, SetState
from quadtank_tui.engine.experiment import format_summary, run_experiment, summarize
from quadtank_tui.engine.history import DEFAULT_CAPACITY
from quadtank_tui.engine.logsession import LogExists, LogRefused, LogSession
from quadtank_tui.engine.driver import LoopTime
from quadtank_tui.engine.runner import ClockKind, Engine, build_engine, load_parameters, virtual_epoch
from quadtank_tui.files.log_writer import SUFFIX, check_log_folder, file_identity
from quadtank_tui.files.names import check_file_name
from quadtank_tui.files.par import ParStore
from quadtank_tui.files.script import Script

#: The exit status of a run that ran to its end but whose interlock held a pump at
#: 0 (an overfull tank): not 0, so a lab's script notices; 1 stays a fault (the
#: link, the log), 2 bad input.
INTERLOCK_ACTED = 3
#: The exit status of a run on a rig cut short at the end of its user's booked slot
#: (or at the start of someone else's): pumps at 0, the log saved with the rows it
#: has.  Not 0: the run is shorter than its --duration.
SLOT_ENDED = 4

#: The ring buffers of a long headless run hold the whole run for the summary, up to
#: this many samples (9 signals x 8 bytes x 2e6 = 144 MB at most).
MAX_HISTORY = 2_000_000
#: The longest run, s of loop time: a week (a lab's longest unattended experiment
#: is a weekend).  `--duration 1e12` was accepted (31,710 years) and `inf` was an
#: OverflowError traceback.
MAX_DURATION = 7 * 86400.0


def check_duration(duration: float, what: str = "--duration") -> float:
    """`duration` if it is a run's length; ValueError saying why not."""
    if not duration > 0:  # NaN too
        raise ValueError(f"{what} must be a positive number of seconds, got {duration:g}")
    if not duration <= MAX_DURATION:
        years = duration / (365.25 * 86400)
        how_long = "forever" if math.isinf(duration) else \
            f"{years:,.0f} years" if years >= 1 else f"{duration / 86400:,.1f} days"
        raise ValueError(f"{what} {duration:g} s would run {how_long}: at most {MAX_DURATION:g} s "
                         f"({MAX_DURATION / 86400:g} days)")
    return duration


@dataclass(frozen=True)
class HeadlessResult:
    status: int
    text: str
    warnings: tuple[str, ...]
    log: Path | None


def run_headless(
    *,
    par: str | None,
    script: Script | None,
    duration: float,
    out: Path,
    seed: int | None = None,
    clock: ClockKind = "manual",
    speed: float | None = None,
    params_dir: Path = Path("params"),
    daq: ProcessBackend | None = None,
    say: Callable[[str], None] | None = None,
    until: Callable[[], str | None] | None = None,
) -> HeadlessResult:
    """Run and save `out`.  Without a script the run logs from the start, for the
    whole duration, in Run.  A `.par` in Automatic starts in Automatic with its
    references (controllers at rest).  With `daq` the run is in Active on that
    process (the clock must then be paced: real time, or the rig's speed factor);
    a link fault pauses it and the status is 1; a run whose interlock held a pump
    at 0 ends with INTERLOCK_ACTED (3) and the summary says which tank, which
    pumps, how many samples and when.  A log that fails (a full disk) ends the run
    at once: `say` (stderr) tells it then, and again on the way out if the run ends
    by an exception (Ctrl-C, SIGTERM); the summary's LOG FAULT line says it at the end.
    `until()`, asked ahead of every sample, is a reason the run must end now (a
    rig's booked slot is over) or None: the run is paused there (pumps at 0), its
    log saved with its rows, the summary's last line says why, status SLOT_ENDED."""
    run = prepare_headless(par=par, script=script, duration=duration, out=out, seed=seed, clock=clock,
                           speed=speed, params_dir=params_dir, daq=daq)
    log = run.engine.loop.log

    def watch(elapsed: LoopTime) -> None:
        error = log.failed
        if error is not None:
            if say is not None:
                say(f"quadtank: LOG FAULT at t = {elapsed.seconds:g} s: {error}; the run stops here")
            raise LogFault(error, elapsed.seconds)
        why = until() if until is not None else None
        if why is not None:
            raise CutShort(why, elapsed.seconds)

    cut: CutShort | None = None
    try:
        try:
            run_experiment(run.engine, script, duration, watch=watch)
        except LogFault as fault:  # said; the summary says it again, over the time it ran
            run = dataclasses.replace(run, duration=fault.at)
        except CutShort as stop:
            cut = stop
            run.engine.submit(SetState("Pause")).result()  # pumps at 0 before anything else
            run = dataclasses.replace(run, duration=stop.at)
        result = finish_headless(run)
    except BaseException:  # Ctrl-C, SIGTERM, SIGHUP, a fault: the log's fault is said on this way out too
        run.engine.stop()
        error = log.error
        if error is not None and say is not None:
            say(f"quadtank: LOG FAULT  {error}")
        raise
    finally:
        run.engine.stop()
    result = _after_stop(result, run.engine)
    if cut is not None:
        saved = f"the log saved as {result.log}" if result.log is not None else "no log saved"
        result = dataclasses.replace(
            result, status=result.status if result.status == 1 else SLOT_ENDED,
            text=f"{result.text}\nSTOPPED    at t = {cut.at:.1f} s of {duration:g}: {cut.reason}; "
                 f"pumps at 0, {saved}")
    return result


class CutShort(Exception):
    """The run must end `at` s of loop time for `reason` (its slot on the rig is over)."""

    def __init__(self, reason: str, at: float) -> None:
        super().__init__(reason)
        self.reason, self.at = reason, at


class LogFault(Exception):
    """The run's log failed (a full disk) `at` s of loop time: the run stops there, its rows kept."""

    def __init__(self, error: str, at: float) -> None:
        super().__init__(error)
        self.at = at


@dataclass(frozen=True)
class HeadlessRun:
    """A headless run ready to sample: its engine (no thread; the caller drives it
    and stops it) and what `finish_headless` needs."""

    engine: Engine
    script: Script | None
    duration: float
    out: Path
    before: tuple[int, ...] | None


def prepare_headless(
    *,
    par: str | None,
    script: Script | None,
    duration: float,
    out: Path,
    seed: int | None = None,
    clock: ClockKind = "manual",
    speed: float | None = None,
    params_dir: Path = Path("params"),
    daq: ProcessBackend | None = None,
) -> HeadlessRun:
    """The engine of `run_headless`, set up (log file, Active, Automatic, LogOn,
    Run as the run asks) and not yet sampled; a session process drives it too."""
    check_duration(duration)
    out = checked_out(out)
    stem = out.name.removesuffix(SUFFIX)
    before = file_identity(out)  # an earlier run's log, which this run replaces
    params, _ = load_parameters(par, ParStore(params_dir))
    capacity = min(MAX_HISTORY, max(DEFAULT_CAPACITY, math.ceil(duration / params.tsamp) + 2))
    engine = build_engine(par, clock=clock, speed=speed, seed=seed, params_dir=params_dir,
                          logs_dir=out.parent, history_capacity=capacity,
                          epoch=virtual_epoch(), daq=daq)
    try:
        # The partial file of an interrupted run sits next to OUT, named after it.
        must(engine.submit(SetParams({"LOGGING.LogFile": stem})).result())
        if daq is not None:
            must(engine.submit(SetOperation("Active")).result())
        if params.control.mode is ControlMode.AUTOMATIC:
            engine.loop.set_initial_mode(ControlMode.AUTOMATIC)
        if script is None or not any(e.action == "log" for e in script.events):
            # Every sample of the run, however many: the writer streams them to disk,
            # so the Logging window's Points limit does not apply.
            points = max(1, math.ceil(duration / params.tsamp - 1e-9))
            must(engine.submit(LogOn(points=points)).result())
        if script is None:
            must(engine.submit(SetState("Run")).result())
    except BaseException:
        engine.stop()
        raise
    return HeadlessRun(engine, script, duration, out, before)


def refuse_log_target(out: Path, *, given: Path | None = None, make_folder: bool = False) -> None:
    """ValueError if `out` (what `--log` named: `given`) is a folder, a device, a
    FIFO or a socket, or its folder does not exist (`make_folder`: it is made)."""
    given = out if given is None else given
    if out.is_dir():
        raise ValueError(f"--log {given}: a folder; --log names the .log to write (e.g. {given / 'run.log'})")
    if out.exists() and not out.is_file():
        raise ValueError(f"--log {given}: not a regular file (a device, a FIFO or a socket); "
                         "--log names the .log to write")
    folder = out.parent
    if make_folder and not folder.exists():
        folder.mkdir(parents=True, exist_ok=True)
    if not folder.is_dir():
        what = "is not a folder" if folder.exists() else "does not exist"
        raise ValueError(f"--log {given}: the folder {folder} {what} (make it first, or name another)")


def checked_out(out: Path, *, make_folder: bool = True) -> Path:
    """The run's `.log` path (`.log` added), its folder checked now, not at a LogOn
    far into the run; ValueError saying what is wrong.  A directory or a device is
    refused: `--log /dev/null` wrote /dev/null.log, `--log /tmp` /tmp.log.  The
    folder is made if missing, but for `--log` (`make_folder` False: `--log
    /nonexistent/x.log` created /nonexistent)."""
    refuse_log_target(out, make_folder=make_folder)
    stem = out.name.removesuffix(SUFFIX)
    try:
        check_file_name(stem, "--log")
    except ParameterError as exc:
        raise ValueError(str(exc)) from None
    refuse_log_target(out.with_name(stem + SUFFIX), given=out, make_folder=make_folder)
    out = out.with_name(stem + SUFFIX)
    check_log_folder(out.parent)
    if out.exists() and not out.is_file():
        raise ValueError(f"{out}: not a regular file; --log names the .log to write")
    return out


def finish_headless(run: HeadlessRun) -> HeadlessResult:
    """After the run: the summary, and the log saved as `run.out`."""
    engine, out, warnings = run.engine, run.out, run.engine.warnings
    summary = summarize(engine, run.duration)
    session = engine.loop.log
    rows, error = session.rows, session.error
    try:
        saved, moved = _save(session, out, run.before)
    except (LogRefused, OSError) as exc:
        text = "\n".join([format_summary(summary), f"no log written: {exc}",
                          *engine.loop.interlock.lines(engine.loop.h), *filter(None, [_unsafe(engine)])])
        return HeadlessResult(1, text, warnings, None)
    text = format_summary(summary) + f"\nlog        {saved} ({rows} rows)"
    if moved:
        warnings = (*warnings, f"{out} was written by another run meanwhile: this run's log is {saved}")
    if session.late_rows:
        text += (f"\nlate       {session.late_rows} of the {rows} rows came late, each after a '% late:' "
                 "line in the log: the device or this computer is too slow for the sampling time")
    if error:
        text += f"\nLOG FAULT  {error}"
    held = engine.loop.interlock.lines(engine.loop.h)
    if held:
        text += "\n" + "\n".join(held)
    unsafe = _unsafe(engine)
    if unsafe:
        text += "\n" + unsafe
    status = 1 if summary.fault or error or unsafe else INTERLOCK_ACTED if held else 0
    return HeadlessResult(status, text, warnings, saved)


def _unsafe(engine: Engine) -> str:
    """A line if the rig's pumps could not be confirmed at 0 ("" if they were)."""
    unsafe = engine.loop.pumps_unconfirmed
    return f"PUMPS      {unsafe.removeprefix('pumps ')}" if unsafe else ""


def _after_stop(result: HeadlessResult, engine: Engine) -> HeadlessResult:
    """The summary with its PUMPS line as the engine's stop left them (its own write
    of 0 may have failed, or confirmed the pumps at 0 at last): 1 if not at 0."""
    lines = [line for line in result.text.splitlines() if not line.startswith("PUMPS ")]
    unsafe = _unsafe(engine)
    if unsafe:
        return dataclasses.replace(result, status=1, text="\n".join([*lines, unsafe]))
    return dataclasses.replace(result, text="\n".join(lines))


def _save(session: LogSession, out: Path, before: tuple[int, ...] | None) -> tuple[Path, bool]:
    """Save the log as `out`, replacing only the file that was there when the run
    began (an earlier run's, which a rerun replaces).  If another run has saved
    `out` meanwhile, its log stays and this one goes to the first free
    `<name>-2.log`, `<name>-3.log`, ...; True then."""
    stem = out.name.removesuffix(SUFFIX)
    try:
        return session.save(out.name, lambda p: file_identity(p) == before), False
    except LogExists:
        pass
    n = 2
    while True:
        try:
            return session.save(f"{stem}-{n}{SUFFIX}", False), True
        except LogExists:
            n += 1


def must(result: CommandResult) -> None:
    """A command's result, refused: ValueError with its message (a scripted run stops)."""
    if not result.ok:
        raise ValueError(result.message)
