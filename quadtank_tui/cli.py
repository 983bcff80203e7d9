"""The `quadtank` command: its parser (each subcommand's from its module in
commands/) and the dispatch: the TUI without a COMMAND (commands/tui.py), the rig's
lock held around what drives a rig, and every failure turned into one line.

Every subcommand turns bad input into one clear line on stderr and exit status 2;
a traceback never reaches the user.
"""

from __future__ import annotations

import argparse
import gc
import signal
import sys
import threading
from typing import Callable, Sequence

from quadtank_tui.commands import UsageError, icad, mpc, say, statefb
from quadtank_tui.commands import analyze as analyze_command
from quadtank_tui.commands import book as book_command
from quadtank_tui.commands import exercise as exercise_command
from quadtank_tui.commands import grade as grade_command
from quadtank_tui.commands import identify as identify_command
from quadtank_tui.commands import lab as lab_command
from quadtank_tui.commands import logs as logs_command
from quadtank_tui.commands import plot as plot_command
from quadtank_tui.commands import run as run_command
from quadtank_tui.commands import serve as serve_command
from quadtank_tui.commands import sessions as sessions_command
from quadtank_tui.commands import tui as tui_command
from quadtank_tui.commands.daq import add_daq_parser, add_rig_parser
from quadtank_tui.commands.design import add_parser as add_design_parser
from quadtank_tui.commands.run import Terminated
from quadtank_tui.core.plants.common import PlantError

# Each subcommand imports what it needs inside its handler: the analysis stack
# (python-control, scipy: over a second), numpy and yaml would otherwise be paid by
# every `quadtank` command, `--help` and the TUI's start included.

Handler = Callable[[argparse.Namespace], int]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="quadtank",
        description="Run and analyse the quadruple-tank laboratory process. "
        "Without a COMMAND: the interactive screen on the simulator.",
    )
    tui_command.add_options(parser)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    analyze_command.add_parser(sub)
    logs_command.add_parser(sub)
    plot_command.add_parser(sub)
    run_command.add_parser(sub)
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
    exercise_command.add_parser(sub, tui_command.cmd_exercise)
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
        missing = tui_command.terminal_missing()
        if missing is not None:  # before anything starts: no session, no lock, no loop
            say(f"quadtank: error: the screen needs a terminal and {missing}; a headless experiment "
                 "runs with `quadtank run` (quadtank run --help)")
            return 2
        handler = tui_command.cmd_tui
    try:
        return _holding_the_daq(handler, args)
    except (UsageError, PlantError, OSError, ValueError) as exc:
        say(f"quadtank: error: {exc}")
        return 2
    except KeyboardInterrupt:
        say("quadtank: interrupted")
        return 130
    except TakenOver:
        say(f"quadtank: stopped (pumps at 0, rows kept): {args.daq_hold.lost_reason}")
        return 1
    except Terminated as exc:
        why = ": a run on a rig is not suspended, its pumps would run on unwatched" \
            if exc.signum == signal.SIGTSTP else ""
        say(f"quadtank: stopped by {exc}{why}")
        return 128 + exc.signum  # the shell's convention: 143 SIGTERM, 129 SIGHUP
    finally:
        gc.enable()  # paused for a TUI's start (pause_gc) that may not have got that far


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
    if args.command == "exercise":  # the TUI in a private session: this process drives the rig
        return args.daq_global
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
        if hold is None or handler is tui_command.cmd_tui:
            return handler(args)
        previous = signal.signal(TAKEN_OVER_SIGNAL, _taken_over)
        main_thread = threading.main_thread().ident
        assert main_thread is not None
        hold.watch(lambda why: signal.pthread_kill(main_thread, TAKEN_OVER_SIGNAL),
                   lambda what: say(f"quadtank: warning: {what}; this run goes on"))
        try:
            return handler(args)
        finally:
            hold.stop_watch()  # before the handler goes: a late signal would end the process
            signal.signal(TAKEN_OVER_SIGNAL, previous)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
