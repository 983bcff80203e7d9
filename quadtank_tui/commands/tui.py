"""The TUI, which `quadtank` starts without a COMMAND: its options, a private session
for this terminal (`--no-session`) or a lab session, and the exercise window
(`quadtank exercise FILE`); the terminal put back and the loop stopped, pumps at 0,
however it ends."""

from __future__ import annotations

import argparse
import gc
import os
import threading
from pathlib import Path
from typing import TYPE_CHECKING

from quadtank_tui.commands import UsageError, pause_gc, say, warn
from quadtank_tui.commands import exercise as exercise_command
from quadtank_tui.commands import lab as lab_command
from quadtank_tui.commands import sessions as sessions_command
from quadtank_tui.commands.daq import add_daq_option
from quadtank_tui.daq.open import open_daq

if TYPE_CHECKING:  # the TUI's modules load only when it starts
    from quadtank_tui.session.client import SessionClient
    from quadtank_tui.ui.app import QuadTankApp


def add_options(parser: argparse.ArgumentParser) -> None:
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


def cmd_tui(args: argparse.Namespace) -> int:
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
        slow = threading.Timer(0.5, say, ("quadtank: stopping the control loop (pumps to 0) ...",))
        slow.start()
        engine.stop()  # stops the private session: the loop, pumps to 0
        slow.cancel()
    if watch.reason is not None:
        _stopped_by(watch.reason)
    if hold is not None and hold.lost_reason is not None:
        say(f"quadtank: stopped (pumps at 0): {hold.lost_reason}")
    return app.return_code or watch.status


def cmd_exercise(args: argparse.Namespace) -> int:
    """`quadtank exercise FILE`: the TUI in a private session with the exercise's window."""
    missing = terminal_missing()
    if missing is not None:
        raise UsageError(f"the exercise window needs a terminal and {missing}; headless: "
                         "quadtank run --exercise FILE --par MINE.par")
    exercise_command.prepare(args)
    return cmd_tui(args)


def _stopped_by(reason: str) -> None:
    """The TUI's last line when its terminal went away ("SIGTERM", "the terminal hung
    up"): after an exit in order, or from the watch that ended it (TerminalWatch)."""
    say(f"quadtank: stopped: {reason}")


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
