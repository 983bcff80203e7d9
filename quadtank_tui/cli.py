"""The `quadtank` command: without a subcommand the TUI (the Main screen) on the
simulator or, with --daq, on the rig; subcommands for analysis, logs and headless
runs.

Every subcommand turns bad input into one clear line on stderr and exit status 2;
a traceback never reaches the user.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import signal
import sys
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

from quadtank_tui.commands import UsageError, icad, pause_gc, warn
from quadtank_tui.commands.design import add_parser as add_design_parser
from quadtank_tui.commands import logview, mpc, statefb
from quadtank_tui.commands import plot as plot_command
from quadtank_tui.commands import identify as identify_command
from quadtank_tui.commands import sessions as sessions_command
from quadtank_tui.commands import lab as lab_command
from quadtank_tui.commands import serve as serve_command
from quadtank_tui.commands import book as book_command
from quadtank_tui.core.plants.common import PlantError
from quadtank_tui.core.plants.johansson import SETTINGS, steady_state_levels
from quadtank_tui.commands import exercise as exercise_command
from quadtank_tui.commands import grade as grade_command
from quadtank_tui.commands.daq import add_daq_option, add_daq_parser, add_rig_parser, run_clock
from quadtank_tui.daq.open import open_daq

# Each subcommand imports what it needs inside its handler: the analysis stack
# (python-control, scipy: over a second), numpy and yaml would otherwise be paid by
# every `quadtank` command, `--help` and the TUI's start included.

#: files.export.FORMATS, written out because that module loads scipy.io just for
#: the parser's choices (tests/cli/test_files_cli.py checks they agree).
EXPORT_FORMATS = ("mat", "csv")


if TYPE_CHECKING:  # the TUI's modules load only when it starts
    from quadtank_tui.core.parameters import Parameters
    from quadtank_tui.core.plants import Plant
    from quadtank_tui.session.client import SessionClient
    from quadtank_tui.ui.app import QuadTankApp


Handler = Callable[[argparse.Namespace], int]


def _add_analyze(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "analyze",
        help="linearize a setting: time constants, G(s), zeros, phase, RGA",
        description="Linearize the quadruple-tank process at an operating point and "
        "print its time constants, transfer matrix, transmission zeros, phase and RGA.",
    )
    source = p.add_mutually_exclusive_group()
    source.add_argument(
        "--preset", choices=sorted(SETTINGS), default="minphase",
        help="named physical setting (default: minphase, the paper's P-)",
    )
    source.add_argument(
        "--par", metavar="FILE",
        help="a .par file: its SIMULATION section gives the plant and operating levels",
    )
    p.add_argument(
        "--at", choices=("levels", "steady"), default="levels",
        help="linearize at the setting's operating levels (default) or at the steady "
        "state of its pump voltages",
    )
    p.add_argument("--json", action="store_true", help="print a JSON object instead of a table")
    p.set_defaults(handler=_cmd_analyze)


def _cmd_analyze(args: argparse.Namespace) -> int:
    from quadtank_tui.core.analysis import analyze, format_report

    h0: Sequence[float]
    if args.par is not None:
        from quadtank_tui.files.par import read_par

        if args.at == "steady":
            raise UsageError("--at steady needs pump voltages; a .par file gives operating levels only")
        read = read_par(args.par)
        warn(read.warnings)
        if read.params.process is not None:  # another rig (core.plants): its generic report
            return _analyze_other_plant(args, read.params)
        params, h0 = read.params.quadtank_constants(), read.params.operating_levels()
        source = {"par": args.par}
        title = f"{args.par}, linearized at its operating levels"
    else:
        setting = SETTINGS[args.preset]
        params, h0 = setting.params, setting.op.x
        where = "operating levels"
        if args.at == "steady":
            h0 = steady_state_levels(setting.op.u, params)
            where = f"steady state of v = ({setting.op.u[0]:.2f}, {setting.op.u[1]:.2f}) V"
        source = {"setting": setting.name}
        title = f"{setting.title}, linearized at the {where}"
    result = analyze(params, h0)
    if args.json:
        print(json.dumps({**source, "linearized_at": args.at, **result.to_dict()}, indent=2))
    else:
        print(format_report(title, result))
    return 0


def _analyze_other_plant(args: argparse.Namespace, params: Parameters) -> int:
    from quadtank_tui.core.plants.report import format_plant_report, report

    plant = params.process_plant()
    result = report(plant, params.process_levels())
    if args.json:
        print(json.dumps({"par": args.par, "linearized_at": args.at, **result.to_dict()}, indent=2))
    else:
        print(format_plant_report(f"{plant.title}, {args.par}, linearized at its operating levels", result))
    return 0


def _add_log(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("log", help="inspect, plot, compare or export .log data files",
                       description="Inspect a .log data file, plot it in the terminal, compare two "
                       "runs' step figures, or export it to .mat / .csv.")
    logsub = p.add_subparsers(dest="log_command", metavar="ACTION", required=True)
    info = logsub.add_parser("info", help="variables, TSamp, rows and duration of a log")
    info.add_argument("file", metavar="FILE")
    info.set_defaults(handler=_cmd_log_info)
    exp = logsub.add_parser("export", help="write a log as .mat (one variable per column + TSamp) or .csv")
    exp.add_argument("file", metavar="FILE")
    exp.add_argument("--to", choices=EXPORT_FORMATS, required=True, help="output format")
    exp.add_argument("--out", metavar="PATH", help="output file (default: FILE with the format's suffix)")
    exp.add_argument("--force", action="store_true", help="overwrite the output file if it exists")
    exp.set_defaults(handler=_cmd_log_export)
    logview.add_parsers(logsub)


def _cmd_log_info(args: argparse.Namespace) -> int:
    from quadtank_tui.files.log_writer import format_tsamp
    from quadtank_tui.files.log_reader import read_log

    log = read_log(args.file)
    warn(log.warnings)
    tsamp = "unknown" if log.tsamp is None else f"{format_tsamp(log.tsamp)} s"
    duration = "unknown" if log.duration is None else f"{log.duration:g} s"
    print(f"file       {args.file}")
    print(f"created    {log.created_text or 'unknown'}")
    print(f"variables  {' '.join(log.variables)}")
    print(f"TSamp      {tsamp}")
    print(f"rows       {log.rows}")
    print(f"duration   {duration}")
    return 0


def _same_file(a: str, b: str) -> bool:
    """Whether two paths name one file (a link too); a path that cannot be looked
    up (missing, a symlink loop) is not the log.  Path.resolve() raised RuntimeError
    on a symlink loop, a traceback instead of an error line."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _cmd_log_export(args: argparse.Namespace) -> int:
    from quadtank_tui.files.export import export_log
    from quadtank_tui.files.log_reader import read_log

    log = read_log(args.file)
    warn(log.warnings)
    out = args.out or str(Path(args.file).with_suffix("." + args.to))
    if _same_file(out, args.file):
        raise UsageError(f"{out}: the export would overwrite the log itself; give --out")
    try:
        print(export_log(log, out, args.to, overwrite=args.force))
    except FileExistsError:
        raise UsageError(f"{out} exists; give --force to overwrite it") from None
    return 0


def _add_run(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run", help="run a (scripted) experiment without the UI and write a .log",
        description="Run the control loop headless on the simulator: apply a YAML "
        "script's timed events, log, and print per-loop figures. Virtual time, as "
        "fast as possible, unless --realtime or --speed is given.",
    )
    p.add_argument("--par", metavar="FILE", help="parameters: a .par file or a name in params/ "
                   "(default: params/default.par, else the built-in values)")
    p.add_argument("--script", metavar="EXP.yaml", help="timed events (see docs/headless.md)")
    p.add_argument("--duration", metavar="SECONDS", type=float,
                   help="length of the run, s (needed but with --inputs-from)")
    p.add_argument("--inputs-from", metavar="LOG",
                   help="drive the simulator open loop with this log's pump signals, from the levels of its "
                   "first row, and write a log whose rows line up with it (a rig's run and its twin)")
    p.add_argument("--log", metavar="OUT.log", help="where the .log is written (needed but with --exercise)")
    p.add_argument("--seed", metavar="N", type=int, help="seed both PRBS generators (N and N + 1)")
    pace = p.add_mutually_exclusive_group()
    pace.add_argument("--realtime", action="store_true", help="keep the sampling time in wall time")
    pace.add_argument("--speed", metavar="X", type=float, help="virtual time at X times real time (1..1000)")
    add_daq_option(p)
    p.add_argument("--detach", action="store_true",
                   help="run it as a lab session and return at once: quadtank attach SESSION watches it, "
                   "quadtank stop SESSION ends it early (the summary goes to the session's output file)")
    lab_command.add_take_over_option(p, dest="take_over")
    exercise_command.add_run_options(p)
    p.set_defaults(handler=_cmd_run)


#: The signals that end a headless run in order (pumps at 0, rows kept), besides
#: SIGINT (KeyboardInterrupt): SIGTERM (systemd, `kill`, `timeout`), SIGHUP (the
#: terminal went away: a dropped SSH session, a closed tmux window) and SIGQUIT
#: (Ctrl-\, whose default would dump core with the pumps running).
STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT)
#: On a rig, Ctrl-Z (SIGTSTP) ends the run too: a suspended loop would leave the
#: pumps at their last value, with nothing watching the levels but the rig's watchdog.
RIG_STOP_SIGNALS = STOP_SIGNALS + (signal.SIGTSTP,)


class Terminated(BaseException):
    """A stop signal (STOP_SIGNALS): unwinds like Ctrl-C, so the run stops with the
    pumps at 0 and its rows kept, instead of dying where it stands.  A BaseException,
    like KeyboardInterrupt: the loop's `except Exception` (a fault pauses the loop
    and carries on) must not swallow it."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _terminate(signum: int, frame: object) -> None:
    raise Terminated(signum)


def _cmd_run(args: argparse.Namespace) -> int:
    from quadtank_tui.engine.headless import check_duration, run_headless
    from quadtank_tui.files.script import read_script

    if args.inputs_from:
        from quadtank_tui.commands.replay import replay

        return replay(args)
    if args.exercise:
        daq_config = args.daq or getattr(args, "daq_global", None)
        clock, daq = run_clock(realtime=args.realtime, speed=args.speed, config=daq_config,
                               plant=_plant_in_use(args.par) if daq_config else None)
        return exercise_command.run_exercise(args, clock, daq, daq_config)
    if args.record:
        raise UsageError("--record keeps an exercise's attempt: it needs --exercise")
    if args.log is None:
        raise UsageError("--log is needed (where the .log is written)")
    if args.duration is None:
        raise UsageError("--duration is needed (the length of the run, s)")
    try:
        check_duration(args.duration)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if args.speed is not None and not 1.0 <= args.speed <= 1000.0:
        raise UsageError(f"--speed must be 1..1000, got {args.speed:g}")
    if args.seed is not None and args.seed < 0:
        raise UsageError(f"--seed must be >= 0, got {args.seed}")
    script = read_script(args.script) if args.script else None
    daq_config = args.daq or getattr(args, "daq_global", None)
    clock, daq = run_clock(realtime=args.realtime, speed=args.speed, config=daq_config,
                           plant=_plant_in_use(args.par) if daq_config else None)
    if args.detach:
        return sessions_command.start_detached_run(args, script, clock)
    previous = {sig: signal.signal(sig, _terminate) for sig in (RIG_STOP_SIGNALS if daq else STOP_SIGNALS)}
    try:
        result = run_headless(par=args.par, script=script, duration=args.duration, out=Path(args.log),
                              seed=args.seed, clock=clock, speed=args.speed, daq=daq)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    warn(result.warnings)
    print(result.text)
    return result.status


def _plant_in_use(par: str | None) -> Plant:
    """The plant of the parameters a run starts from (`--par`, else the defaults):
    the DAQ configuration is read for its channels."""
    from quadtank_tui.engine.runner import load_parameters
    from quadtank_tui.files.par import ParStore

    return load_parameters(par, ParStore(Path("params")))[0].process_plant()


def _add_tui_options(parser: argparse.ArgumentParser) -> None:
    """Options of the TUI, which starts when no COMMAND is given.  Their own dests
    keep them apart from `run`'s options of the same names."""
    tui = parser.add_argument_group("the TUI (no COMMAND)")
    tui.add_argument("--par", metavar="FILE", dest="tui_par",
                     help="parameters: a .par file or a name in params/ "
                     "(default: params/default.par, else the built-in values)")
    add_daq_option(tui, dest="daq_global")
    lab_command.add_take_over_option(tui, dest="take_over_global")
    tui.add_argument("--speed", metavar="X", type=float, default=1.0, dest="tui_speed",
                     help="simulated seconds per wall second at start (1..1000; keys + and - change it)")
    tui.add_argument("--refresh", metavar="SECONDS", type=float, default=0.05,
                     help="screen refresh interval (default 0.05; raise it on a slow link)")
    tui.add_argument("--no-session", action="store_true",
                     help="run the loop in a private session for this terminal only (unlisted; it "
                     "stops, pumps at 0, when the TUI ends) instead of in a lab session that "
                     "outlives the terminal (see quadtank sessions)")


def build_tui(args: argparse.Namespace) -> tuple[SessionClient, QuadTankApp]:
    """`--no-session`: a private session (the session process and protocol of the
    default, for this terminal only: unlisted, it stops with this process) and the
    app on it.  A rig (--daq) keeps wall time; the simulator runs on a virtual clock
    so a student can speed it up.  The rig's lock stays with this process."""
    from quadtank_tui.engine.runner import engine_spec
    from quadtank_tui.session.launch import SessionSpec, Spawned

    if not 1.0 <= args.tui_speed <= 1000.0:
        raise UsageError(f"--speed must be 1..1000, got {args.tui_speed:g}")
    if not 0.01 <= args.refresh <= 5.0:
        raise UsageError(f"--refresh must be 0.01..5 s, got {args.refresh:g}")
    # The session process boots (a fresh interpreter, numpy) while this one checks
    # the files and loads the UI: the first frame comes that much sooner.
    spawned = Spawned(private=True)
    try:
        spec = engine_spec(args.tui_par, clock="realtime" if args.daq_global else "virtual", speed=args.tui_speed)
        # the configuration is checked here, in any case, for the plant of the parameters
        open_daq(args.daq_global, spec.params.process_plant() if args.daq_global else None, warn=warn)
        daq = args.daq_global and str(Path(args.daq_global).resolve())
        spawned.hand_over(SessionSpec(spec, str(sessions_command.runtime_folder()), daq, private=True))
        from quadtank_tui.session.client import SessionClient
        from quadtank_tui.ui.app import build_app

        info = spawned.wait_ready()
        client = SessionClient(info.socket, private=True, let_go=spawned.let_go, expect=info)
    except BaseException:
        spawned.cancel()
        raise
    client.warnings = tuple(spec.warnings)
    return client, build_app(client, refresh_interval=args.refresh, resume_gc=not gc.isenabled(),
                             read_on=client.read_on, exercise=getattr(args, "exercise_tracker", None))


def _cmd_tui(args: argparse.Namespace) -> int:
    """The TUI until Exit, a crash (status 1), or its terminal going away (a hang-up,
    SIGHUP, SIGTERM: status 129 / 143, within about a second); in every case the
    terminal is put back and the loop stopped with the pumps at 0."""
    from quadtank_tui.ui.terminal_watch import TerminalWatch

    if not args.no_session:
        return sessions_command.cmd_tui_session(args)
    pause_gc()
    engine, app = build_tui(args)
    warn(engine.warnings)
    watch = TerminalWatch(app.exit_soon, engine.stop, farewell=_stopped_by)
    hold = getattr(args, "daq_hold", None)  # the rig's lock (main takes it): lost, the TUI ends
    if hold is not None:
        hold.watch(lambda why: app.exit_soon(1))
    engine.start()
    watch.start()
    try:
        app.run()
    finally:
        watch.close()
        # A hung DAQ holds the loop for a timeout or two: say what the wait is for.
        slow = threading.Timer(0.5, _say, ("quadtank: stopping the control loop (pumps to 0) ...",))
        slow.start()
        engine.stop()  # stops the private session: the loop, pumps to 0
        slow.cancel()
    if watch.reason is not None:
        _stopped_by(watch.reason)
    if hold is not None and hold.lost_reason is not None:
        _say(f"quadtank: stopped (pumps at 0): {hold.lost_reason}")
    return app.return_code or watch.status


def _cmd_exercise(args: argparse.Namespace) -> int:
    """`quadtank exercise FILE`: the TUI in a private session with the exercise's window."""
    missing = terminal_missing()
    if missing is not None:
        raise UsageError(f"the exercise window needs a terminal and {missing}; headless: "
                         "quadtank run --exercise FILE --par MINE.par")
    exercise_command.prepare(args)
    return _cmd_tui(args)


def _stopped_by(reason: str) -> None:
    """The TUI's last line when its terminal went away ("SIGTERM", "the terminal hung
    up"): after an exit in order, or from the watch that ended it (TerminalWatch)."""
    _say(f"quadtank: stopped: {reason}")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="quadtank",
        description="Run and analyse the quadruple-tank laboratory process. "
        "Without a COMMAND: the interactive screen on the simulator.",
    )
    _add_tui_options(parser)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    _add_analyze(sub)
    _add_log(sub)
    plot_command.add_parser(sub)
    _add_run(sub)
    add_rig_parser(sub)
    add_daq_parser(sub)
    icad.add_parser(sub)
    add_design_parser(sub)
    statefb.add_parser(sub)
    mpc.add_parser(sub)
    identify_command.add_parser(sub)
    sessions_command.add_parsers(sub)
    lab_command.add_parser(sub)
    serve_command.add_parser(sub)
    exercise_command.add_parser(sub, _cmd_exercise)
    book_command.add_parsers(sub)
    grade_command.add_parser(sub)
    return parser


#: options whose value is a transfer-function expression, which may start with a minus
EXPRESSION_OPTIONS = ("--model", "--evaluate-on")


def joined_expressions(argv: Sequence[str]) -> list[str]:
    """`--model -0.0065*exp(-2*s)/s` as `--model=-0.0065*exp(-2*s)/s`: argparse takes a
    value starting with '-' for an option unless it is joined with '='."""
    out: list[str] = []
    items = list(argv)
    i = 0
    while i < len(items):
        a = items[i]
        if a in EXPRESSION_OPTIONS and i + 1 < len(items) and items[i + 1].startswith("-") \
                and not items[i + 1].startswith("--") and len(items[i + 1]) > 1 and not items[i + 1][1].isalpha():
            out.append(f"{a}={items[i + 1]}")
            i += 2
            continue
        out.append(a)
        i += 1
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(joined_expressions(sys.argv[1:] if argv is None else argv))
    handler: Handler | None = getattr(args, "handler", None)
    if handler is None:
        missing = terminal_missing()
        if missing is not None:  # before anything starts: no session, no lock, no loop
            _say(f"quadtank: error: the screen needs a terminal and {missing}; a headless experiment "
                 "runs with `quadtank run` (quadtank run --help)")
            return 2
        handler = _cmd_tui
    try:
        return _holding_the_daq(handler, args)
    except (UsageError, PlantError, OSError, ValueError) as exc:
        _say(f"quadtank: error: {exc}")
        return 2
    except KeyboardInterrupt:
        _say("quadtank: interrupted")
        return 130
    except TakenOver:
        _say(f"quadtank: stopped (pumps at 0, rows kept): {args.daq_hold.lost_reason}")
        return 1
    except Terminated as exc:
        why = ": a run on a rig is not suspended, its pumps would run on unwatched" \
            if exc.signum == signal.SIGTSTP else ""
        _say(f"quadtank: stopped by {exc}{why}")
        return 128 + exc.signum  # the shell's convention: 143 SIGTERM, 129 SIGHUP
    finally:
        gc.enable()  # paused for a TUI's start (pause_gc) that may not have got that far


def terminal_missing() -> str | None:
    """Why the screen cannot run here: stdin or stdout closed (`quadtank <&-`) or
    not a terminal (a pipe, a file, cron); None when both are terminals.  A browser
    tab of `quadtank serve` runs Textual's web driver, whose screen is a pipe."""
    if os.environ.get("TEXTUAL_DRIVER") == "textual.drivers.web_driver:WebDriver":
        return None
    for fd, name in ((0, "stdin"), (1, "stdout")):
        try:
            os.fstat(fd)
        except OSError:
            return f"{name} is closed"
        if not os.isatty(fd):
            return f"{name} is not one"
    return None


def _driven_daq(args: argparse.Namespace) -> str | None:
    """The DAQ configuration of the rig this command drives (writes pumps to), if any:
    the TUI and `run` with --daq, `daq calibrate` on a rig; `daq check` only reads."""
    if args.command is None:  # the TUI; on a rig your own session drives, it attaches to that session
        session = not args.no_session
        # Looked up once (a DAQ file read, a name resolved): cmd_tui_session attaches to it.
        args.own_rig_session = sessions_command.own_session_on_rig(args.daq_global) if session else None
        return None if args.own_rig_session else args.daq_global
    if args.command == "run":
        return args.daq or args.daq_global
    if args.command == "daq" and args.daq_command == "calibrate" and args.pairs is None:
        return args.config
    return None


class TakenOver(BaseException):
    """An administrator took the rig over (--take-over): a headless command unwinds
    as from Ctrl-C (pumps at 0, rows kept).  A BaseException, like Terminated."""


def _taken_over(signum: int, frame: object) -> None:
    raise TakenOver()


#: The signal the lock's watch thread sends the main thread when the rig is taken
#: over: a real signal interrupts a sleep between samples (up to TSamp, 10 s).
TAKEN_OVER_SIGNAL = signal.SIGUSR1


def _holding_the_daq(handler: Handler, args: argparse.Namespace) -> int:
    """Run `handler` holding the lock of the rig it drives (refused, exit 2, if another
    program drives it).  A headless command whose rig is taken over is interrupted
    (TakenOver); the TUI watches its lock itself (args.daq_hold)."""
    take_over = getattr(args, "take_over", False) or args.take_over_global
    driven = _driven_daq(args)
    if driven is not None and not take_over:
        book_command.refuse_in_anothers_slot(driven)  # the rig's bookings: UsageError in someone else's slot
    with lab_command.hold_daq(driven, take_over=take_over) as hold:
        args.daq_hold = hold
        if hold is None or handler is _cmd_tui:
            return handler(args)
        previous = signal.signal(TAKEN_OVER_SIGNAL, _taken_over)
        main_thread = threading.main_thread().ident
        assert main_thread is not None
        hold.watch(lambda why: signal.pthread_kill(main_thread, TAKEN_OVER_SIGNAL),
                   lambda what: _say(f"quadtank: warning: {what}; this run goes on"))
        try:
            return handler(args)
        finally:
            hold.stop_watch()  # before the handler goes: a late signal would end the process
            signal.signal(TAKEN_OVER_SIGNAL, previous)


def _say(line: str) -> None:
    """One line on stderr; after a hang-up the terminal is gone and writing to it
    fails (EIO), which must not turn a clean stop into a traceback."""
    try:
        print(line, file=sys.stderr, flush=True)
    except OSError:
        pass


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
