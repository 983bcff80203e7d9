"""`quadtank` on a session, and `quadtank sessions | attach | stop`.

`quadtank` attaches to the caller's running session, else starts one (detached:
it survives the terminal) and attaches to it; the TUI is a client.  Its Exit asks
whether to stop the session or detach; losing the terminal detaches (within a
second) and never stops the session.
"""

from __future__ import annotations

import argparse
import gc
import os
import threading
from pathlib import Path
from typing import TYPE_CHECKING

from quadtank_tui.commands import UsageError, pause_gc, say, warn

if TYPE_CHECKING:
    from quadtank_tui.session.launch import SessionSpec
    from quadtank_tui.session.riglock import RigLock
    from quadtank_tui.engine.runner import ClockKind
    from quadtank_tui.files.script import Script
    from quadtank_tui.session.client import SessionClient
    from quadtank_tui.session.info import SessionInfo
    from quadtank_tui.session.protocol import Role
    from quadtank_tui.ui.windows.attached import AttachedNotice


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("sessions", help="list the lab sessions on this machine",
                       description="The running sessions: id, owner, started, plant, Simul/Active, "
                       "Run/Pause, logging progress, attached clients; then the sessions that ended "
                       "in the last 7 days, each with why.")
    p.add_argument("--json", action="store_true", help="one JSON object per session, a list (an ended "
                   "session's `ended` says why)")
    p.set_defaults(handler=cmd_sessions)
    a = sub.add_parser("attach", help="attach the TUI to a running session",
                       description="Attach the TUI to SESSION (default: your only running session).")
    a.add_argument("session", metavar="SESSION", nargs="?", help="a session id (see quadtank sessions)")
    a.add_argument("--observe", action="store_true", help="watch read-only: every command is refused")
    a.add_argument("--take-over", action="store_true",
                   help="take the operator's place: from your own other screen (a link that died unnoticed), "
                   "or anyone's as an administrator (the operator becomes an observer)")
    a.add_argument("--refresh", metavar="SECONDS", type=float, default=0.05, dest="attach_refresh",
                   help="screen refresh interval (default 0.05)")
    a.set_defaults(handler=cmd_attach)
    s = sub.add_parser("stop", help="stop a session: pumps at 0, log kept",
                       description="Stop SESSION: the pumps at 0, logging stopped with its rows kept "
                       "(an unsaved log stays in the partial file), the process gone.")
    s.add_argument("session", metavar="SESSION", help="a session id (see quadtank sessions)")
    s.set_defaults(handler=cmd_stop)


def runtime_folder() -> Path:
    from quadtank_tui.session.runtime import runtime_dir

    return runtime_dir()


# --- quadtank sessions ---------------------------------------------------------------------------


def cmd_sessions(args: argparse.Namespace) -> int:
    import json
    from dataclasses import asdict

    from quadtank_tui.session.runtime import ended_sessions, list_sessions

    runtime = runtime_folder()
    ended = ended_sessions(runtime)  # first: marks the dead ones ended
    sessions = list_sessions(runtime, prune=False)
    if args.json:
        print(json.dumps([asdict(i) for i in sessions + ended], indent=2))
        return 0
    if not sessions and not ended:
        print("no sessions")
    else:
        print(format_table(sessions) if sessions else "no running sessions")
        if ended:
            print(f"\nended (kept {_kept()}):\n" + format_ended(ended))
    _name_the_ignored(runtime)
    return 0


#: Ignored files named by `quadtank sessions`, at most (a folder of junk is one line more).
MAX_IGNORED_SHOWN = 20


def _name_the_ignored(runtime: Path) -> None:
    """For an administrator: the files of the runtime folder that are no one's
    record (a FIFO, a link, a record the OS disagrees with), each with why."""
    from quadtank_tui.files.shared import shown
    from quadtank_tui.session.lab import load_lab_config
    from quadtank_tui.session.roles import is_administrator
    from quadtank_tui.session.runtime import ignored_records

    if not is_administrator(os.getuid(), load_lab_config()):
        return
    ignored = ignored_records(runtime)
    if ignored:
        print("\nignored (not what the operating system says; an administrator may remove them):")
        for item in ignored[:MAX_IGNORED_SHOWN]:
            print(f"  {shown(item.why)}")
        if len(ignored) > MAX_IGNORED_SHOWN:
            print(f"  ... and {len(ignored) - MAX_IGNORED_SHOWN} more")


def _kept() -> str:
    from quadtank_tui.session.runtime import ENDED_KEPT, ENDED_PER_OWNER

    return f"{ENDED_KEPT.days} days, the last {ENDED_PER_OWNER} of each owner"


def format_ended(sessions: list[SessionInfo]) -> str:
    """The ended sessions, one a line: when and why (the reason last: it may be long)."""
    from quadtank_tui.files.shared import shown

    head = ("ID", "OWNER", "STARTED", "ENDED", "WHY")
    rows = [head] + [tuple(map(shown, (i.id, i.owner, i.started.replace("T", " "),
                                       i.ended_at.replace("T", " ") or "?", i.ended)))
                     for i in sessions]
    widths = [max(len(r[c]) for r in rows) for c in range(len(head) - 1)]
    return "\n".join("  ".join([*(v.ljust(w) for v, w in zip(r, widths)), r[-1]]).rstrip() for r in rows)


def format_table(sessions: list[SessionInfo]) -> str:
    """The running sessions, one a line; what a record says shown with its control
    characters escaped (another user wrote it: files.shared.shown)."""
    from quadtank_tui.files.shared import shown

    head = ("ID", "OWNER", "STARTED", "PLANT", "OPERATION", "STATE", "LOGGING", "CLIENTS")
    rows: list[tuple[str, ...]] = [head]
    for i in sessions:
        clients = f"{i.clients}" + (f" ({i.operator} operates)" if i.operator else "")
        state = i.state + (f" - {i.note}" if i.note else "")
        operation = i.operation + (" (no watchdog)" if i.daq and i.watchdog == "none" else "")
        rows.append(tuple(map(shown, (i.id, i.owner, i.started.replace("T", " "),
                                      i.plant + (" (headless)" if i.headless else ""),
                                      operation, state, i.logging, clients))))
    widths = [max(len(r[c]) for r in rows) for c in range(len(head))]
    return "\n".join("  ".join(v.ljust(w) for v, w in zip(r, widths)).rstrip() for r in rows)


# --- quadtank stop -------------------------------------------------------------------------------


def cmd_stop(args: argparse.Namespace) -> int:
    from quadtank_tui.session.client import SessionError, stop_session_at
    from quadtank_tui.files.proc import pid_alive
    from quadtank_tui.session.runtime import NoSession, find_session

    try:
        info = find_session(runtime_folder(), args.session, os.getuid())
        reason = stop_session_at(info.socket, expect=info)
    except (NoSession, SessionError) as exc:
        raise UsageError(str(exc)) from None
    for _ in range(200):  # the process ends right after it said so
        if not pid_alive(info.pid):
            break
        threading.Event().wait(0.05)
    from quadtank_tui.files.shared import shown

    print(f"session {info.id} stopped ({shown(reason)}): pumps at 0, logging stopped, its rows kept in "
          f"{shown(info.cwd)}")
    return 0


# --- the TUI on a session ------------------------------------------------------------------------


def cmd_attach(args: argparse.Namespace) -> int:
    from quadtank_tui.session.client import SessionError
    from quadtank_tui.session.runtime import NoSession, find_session

    if not 0.01 <= args.attach_refresh <= 5.0:
        raise UsageError(f"--refresh must be 0.01..5 s, got {args.attach_refresh:g}")
    pause_gc()
    try:
        info = find_session(runtime_folder(), args.session, os.getuid())
        client = _connect(info, "observer" if args.observe else "operator", take_over=args.take_over)
    except (NoSession, SessionError) as exc:
        raise UsageError(str(exc)) from None
    return run_tui_on(client, args.attach_refresh)


def _connect(info: SessionInfo, role: Role, *, take_over: bool = False) -> SessionClient:
    from quadtank_tui.session.client import SessionClient

    return SessionClient(info.socket, role=role, take_over=take_over, expect=info)


def cmd_tui_session(args: argparse.Namespace) -> int:
    """`quadtank` with sessions: attach to the caller's running session, else start one."""
    from quadtank_tui.session.runtime import NoSession, find_session

    if not 1.0 <= args.tui_speed <= 1000.0:
        raise UsageError(f"--speed must be 1..1000, got {args.tui_speed:g}")
    if not 0.01 <= args.refresh <= 5.0:
        raise UsageError(f"--refresh must be 0.01..5 s, got {args.refresh:g}")
    attached = attach_to_own_rig_session(args)
    if attached is not None:
        return attached
    pause_gc()
    runtime = runtime_folder()
    try:
        info = find_session(runtime, None, os.getuid(), interactive=True)
    except NoSession as exc:
        if "name one" in str(exc):
            raise UsageError(f"{exc} with quadtank attach SESSION") from None
        info = None
    notice = None
    if info is None:
        info = _start_while_loading_the_ui(args, runtime)
    elif args.tui_par or args.daq_global:
        notice = attached_notice(info, args)
    from quadtank_tui.session.client import SessionError, stop_session_at

    try:
        client = _connect(info, "operator")
    except SessionError as exc:
        raise UsageError(str(exc)) from None
    if notice is None:
        return run_tui_on(client, args.refresh)
    status, new = _run_tui(client, args.refresh, notice)
    if not new:
        return status
    # the attached window's `n`: that session stops, one with these options starts
    try:
        reason = stop_session_at(info.socket, expect=info)
    except SessionError as exc:
        raise UsageError(f"session {info.id} did not stop ({exc}): no new session started") from None
    say(f"quadtank: session {info.id} stopped ({reason}); starting a new one")
    info = _start_while_loading_the_ui(args, runtime)
    try:
        client = _connect(info, "operator")
    except SessionError as exc:
        raise UsageError(str(exc)) from None
    return run_tui_on(client, args.refresh)


def attached_notice(info: SessionInfo, args: argparse.Namespace) -> AttachedNotice:
    """What the TUI says first when it attached to `info` although `--par` / `--daq`
    asked for something that only a new session takes."""
    from quadtank_tui.files.shared import shown
    from quadtank_tui.ui.windows.attached import AttachedNotice

    plant = (f"the rig of {shown(info.daq)} ({info.operation})" if info.daq
             else f"the simulator ({info.operation})")
    ignored = tuple(f"{name} {value}" for name, value in (("--daq", args.daq_global), ("--par", args.tui_par))
                    if value)
    return AttachedNotice(info.id, plant, ignored)


def own_session_on_rig(config: str | None) -> tuple[SessionInfo, str] | None:
    """The caller's running session that drives the rig the DAQ configuration
    `config` names (it holds the rig's lock), and the rig's lock key; None when the
    rig is free, someone else's, or the file or host is bad (the lock's own path
    then says so)."""
    if config is None:
        return None
    from quadtank_tui.daq.open import load_rig_config
    from quadtank_tui.session.lab import load_lab_config
    from quadtank_tui.session.lock import holder_of
    from quadtank_tui.session.riglock import rig_keys
    from quadtank_tui.session.runtime import list_sessions

    try:
        rig = load_rig_config(config)
        lab = load_lab_config()
        devices = rig_keys(rig)
    except (ValueError, OSError):
        return None
    for device in devices:
        held = holder_of(device, lab)
        if held is None or held.uid != os.getuid() or held.session is None:
            continue
        for info in list_sessions(runtime_folder()):
            if info.id == held.session and info.pid == held.pid:
                return info, device
    return None


def attach_to_own_rig_session(args: argparse.Namespace) -> int | None:
    """`quadtank --daq C` while the caller's own session drives that rig: attach to
    it, saying so (its exit status), instead of refusing; None otherwise."""
    from quadtank_tui.session.client import SessionError

    # cli._driven_daq looked it up before taking the rig's lock (main always runs it)
    own = args.own_rig_session if hasattr(args, "own_rig_session") else own_session_on_rig(args.daq_global)
    if own is None:
        return None
    info, device = own
    say(f"quadtank: the rig at {device} is driven by your session {info.id}: attaching to it"
         + (" (--par applies to a new session only)" if args.tui_par else ""))
    try:
        client = _connect(info, "operator")
    except SessionError as exc:
        raise UsageError(str(exc)) from None
    return run_tui_on(client, args.refresh)


def _start_while_loading_the_ui(args: argparse.Namespace, runtime: Path) -> SessionInfo:
    """A new session, started so that its boot (a fresh interpreter, numpy, the
    engine: about 0.3 s) and this process's work (checking the files, loading the
    UI: about 0.35 s) overlap instead of adding up before the first frame
    (benchmarks/tui_cost.py): the process is spawned first, then handed the checked
    spec.  Refused files end it unseen; so does any failure here before it is ready."""
    from quadtank_tui.session.launch import Spawned

    spawned = Spawned()
    try:
        spawned.hand_over(_checked_spec(args, runtime), lock=_held_lock(args))
        import quadtank_tui.ui.app  # noqa: F401  (used by run_tui_on, loaded meanwhile)
        return spawned.wait_ready()
    except BaseException:
        spawned.cancel()
        raise


def _checked_spec(args: argparse.Namespace, runtime: Path) -> SessionSpec:
    """The session spec for the TUI's options; a bad .par or DAQ file is refused here,
    in the terminal, with the usual message."""
    from quadtank_tui.daq.open import open_daq
    from quadtank_tui.engine.runner import engine_spec
    from quadtank_tui.session.launch import SessionSpec

    spec = engine_spec(args.tui_par, clock="realtime" if args.daq_global else "virtual", speed=args.tui_speed)
    # The DAQ configuration is checked here, for the plant of the parameters.
    open_daq(args.daq_global, spec.params.process_plant() if args.daq_global else None, warn=warn)
    warn(spec.warnings)
    return SessionSpec(spec, str(runtime), args.daq_global and str(Path(args.daq_global).resolve()))


def _held_lock(args: argparse.Namespace) -> RigLock | None:
    """The rig's lock `quadtank` took for this command (cli.main), to hand over to
    the session (which watches it from then on: this process stops watching)."""
    hold = getattr(args, "daq_hold", None)
    if hold is None:
        return None
    hold.stop_watch()
    return hold.lock


def _has_disturbance_pumps(config: str) -> bool:
    """Whether the rig a DAQ file describes has disturbance pumps (an IST rig)."""
    from quadtank_tui.daq.ist.config import IstConfig
    from quadtank_tui.daq.open import load_rig_config

    return isinstance(load_rig_config(config), IstConfig)


def start_detached_run(args: argparse.Namespace, script: Script | None, clock: ClockKind) -> int:
    """`quadtank run ... --detach`: the run in a session process; returns at once,
    once its options and its script have been checked here (a refusal is said in
    the terminal, exit 2, not in the session's output after it detached)."""
    from quadtank_tui.engine.headless import checked_out
    from quadtank_tui.engine.runner import load_parameters
    from quadtank_tui.files.par import ParStore
    from quadtank_tui.session.launch import HeadlessArgs, SessionSpec, start_session
    from quadtank_tui.session.scripted import rehearse

    _, warnings = load_parameters(args.par, ParStore("params"))  # a bad .par is refused here
    warn(warnings)
    config = args.daq or getattr(args, "daq_global", None)
    checked_out(Path(args.log))  # the log's name and folder
    partly = rehearse(par=args.par, script=script, duration=args.duration, out=Path(args.log), seed=args.seed,
                      params_dir=Path("params"), active=config is not None,  # the script's refusals
                      disturbance_pumps=config is not None and _has_disturbance_pumps(config))
    warn([partly] if partly else [])
    run = HeadlessArgs(args.par, script, args.duration, str(Path(args.log).resolve()), args.seed, clock,
                       args.speed, str(Path("params").resolve()))
    runtime = runtime_folder()
    info = start_session(SessionSpec(None, str(runtime), config and str(Path(config).resolve()), run),
                         lock=_held_lock(args))
    print(f"session {info.id} runs the experiment ({args.duration:g} s) and will save {run.out}; "
          f"quadtank attach {info.id} watches it, quadtank stop {info.id} ends it early; "
          f"its summary goes to {Path(info.socket).with_suffix('.out')}")
    return 0


def run_tui_on(client: SessionClient, refresh: float) -> int:
    """The TUI on `client` until Exit or the terminal goes; then detach (or stop the
    session, if Exit chose that)."""
    return _run_tui(client, refresh)[0]


def _run_tui(client: SessionClient, refresh: float, attached: AttachedNotice | None = None) -> tuple[int, bool]:
    """run_tui_on, with `attached`: the window shown first (options the session did
    not take); also whether its user asked for a new session instead."""
    from quadtank_tui.ui.app import build_app
    from quadtank_tui.ui.terminal_watch import TerminalWatch

    app = build_app(client, refresh_interval=refresh, resume_gc=not gc.isenabled(), read_on=client.read_on,
                    attached=attached)
    watch = TerminalWatch(app.exit_soon, client.close, farewell=lambda why: say(after_the_screen(client, why)))
    watch.start()
    try:
        app.run()
    finally:
        watch.close()
        client.close()  # detaches; stops the session if Exit chose that
    if app.new_session_asked and watch.reason is None:
        return 0, True
    say(after_the_screen(client, watch.reason))
    return app.return_code or watch.status, False


def after_the_screen(client: SessionClient, hung_up: str | None) -> str:
    """The line the terminal gets once the TUI on `client` is gone; `hung_up`: the
    terminal went away (why)."""
    sid = client.info.id
    if hung_up is not None:
        return f"quadtank: detached from session {sid}: {hung_up}; it keeps running"
    if client.dropped is not None and client.ended is None and not client.private:
        return (f"quadtank: session {sid} dropped this screen ({client.dropped}); it keeps running: "
                f"quadtank attach {sid} comes back to it")
    if client.stop_on_close:
        return f"quadtank: session {sid} stopped" + ("" if client.ended else " (it did not confirm)")
    if client.gone and client.ended is not None:
        return f"quadtank: session {sid} ended: {client.ended}"
    return (f"quadtank: detached from session {sid}: quadtank attach {sid} comes back to it, "
            f"quadtank stop {sid} stops it. {client.policy}")
