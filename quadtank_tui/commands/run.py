"""`quadtank run`: the control loop headless on the simulator or a rig: a script's
timed events, a log, the per-loop figures; stopped in order (pumps at 0, rows kept)
by a signal."""

from __future__ import annotations

import argparse
import signal
from pathlib import Path
from typing import TYPE_CHECKING

from quadtank_tui.commands import UsageError, say, warn
from quadtank_tui.commands import book as book_command
from quadtank_tui.commands import exercise as exercise_command
from quadtank_tui.commands import lab as lab_command
from quadtank_tui.commands import sessions as sessions_command
from quadtank_tui.commands.daq import add_daq_option, run_clock

if TYPE_CHECKING:
    from quadtank_tui.core.plants import Plant


def add_parser(sub: argparse._SubParsersAction) -> None:
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
    from quadtank_tui.engine.headless import check_duration, checked_out, run_headless
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
        checked_out(Path(args.log), make_folder=False)  # before a session or a file is made
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
    # on a rig: the run ends at its user's booked slot's end (or at someone else's slot's start)
    until = book_command.slot_end_watch(daq_config) if daq is not None and daq_config else None
    previous = {sig: signal.signal(sig, _terminate) for sig in (RIG_STOP_SIGNALS if daq else STOP_SIGNALS)}
    try:
        result = run_headless(par=args.par, script=script, duration=args.duration, out=Path(args.log),
                              seed=args.seed, clock=clock, speed=args.speed, daq=daq, say=say, until=until)
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
