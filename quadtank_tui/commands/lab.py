"""`quadtank lab` (the lab configuration in force, and the unattended policy an
administrator sets) and the DAQ lock every program that drives a rig takes first
(`hold_daq`): the TUI with --daq, `quadtank run --daq`, `quadtank daq calibrate`.

The lock is taken before anything is written to the rig and released on every way
out (an exception, Ctrl-C, SIGTERM, a hang-up); a holder killed outright (SIGKILL)
leaves a stale record the next program takes over.  A second program is refused
with one line naming the holder; an administrator may take the rig over
(--take-over), and the program that held it then stops (pumps at 0) and says why.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterator

from quadtank_tui.commands import UsageError

# The session modules load yaml (the lab file): imported inside the functions, so
# building the parser, which every `quadtank` command does, stays cheap.
if TYPE_CHECKING:
    from quadtank_tui.session.lab import LabConfig
    from quadtank_tui.session.lock import DaqLock
    from quadtank_tui.session.lockwatch import LockWatch
    from quadtank_tui.session.riglock import RigLock

#: Seconds a take-over waits for the previous holder to stop driving the rig
#: (its LockWatch notices within 0.5 s; its loop then puts the pumps at 0).
TAKE_OVER_WAIT = 10.0


class DaqHold:
    """A DAQ lock held by this program, and the watch that notices a take-over."""

    def __init__(self, lock: DaqLock | RigLock) -> None:
        self.lock = lock
        self._watch: LockWatch | None = None

    @property
    def lost_reason(self) -> str | None:
        """Why the program stopped driving the rig (taken over), None while it drives it."""
        return None if self._watch is None else self._watch.reason

    def watch(self, on_lost: Callable[[str], None], on_note: Callable[[str], None] | None = None) -> None:
        """Call `on_lost(reason)` (from another thread) if the lock is taken over, and
        `on_note(what)` when a forged or refused record was replaced by ours."""
        from quadtank_tui.session.lockwatch import LockWatch

        if self._watch is None:
            self._watch = LockWatch(self.lock, on_lost, on_note=on_note).start()

    def stop_watch(self) -> None:
        if self._watch is not None:
            self._watch.stop()

    def close(self) -> None:
        self.stop_watch()
        self.lock.release()


def add_take_over_option(parser: argparse.ArgumentParser | argparse._ArgumentGroup, *, dest: str) -> None:
    parser.add_argument("--take-over", action="store_true", dest=dest,
                        help="administrators: take the rig over from the program that drives it "
                        "(it stops, pumps at 0)")


@contextmanager
def hold_daq(config: str | None, *, take_over: bool = False, say: Callable[[str], None] | None = None
             ) -> Iterator[DaqHold | None]:
    """The DAQ lock of the rig the DAQ configuration `config` names, for the
    duration of the block (None without a configuration).  UsageError naming the
    holder if another program drives it; NotPermitted for a take-over by a
    non-administrator; UsageError if the holder did not stop within TAKE_OVER_WAIT
    (by its lab's rules the taker is no administrator): the lock is given back."""
    if config is None:
        yield None
        return
    from quadtank_tui.session import roles
    from quadtank_tui.session.lab import load_lab_config
    from quadtank_tui.files.proc import pid_alive
    from quadtank_tui.session.lock import DaqLockHeld
    from quadtank_tui.session.riglock import RigLock

    from quadtank_tui.daq.open import load_rig_config

    rig = load_rig_config(config)  # a bad file is reported here, before anything else
    lab = load_lab_config()

    def acquire(take_over: bool = False) -> RigLock:
        return RigLock.of(rig, lab, take_over=take_over)  # under the rig's identity (riglock.rig_keys)

    try:  # under every address the host resolves to (a name that does not: refused)
        lock = acquire()
    except DaqLockHeld as held:
        device = held.device
        if not take_over:
            raise UsageError(f"{held}; ask them to stop it, or an administrator may take it over "
                             "(--take-over)") from None
        me = roles.current_user()
        roles.require_administrator(me.uid, lab, f"taking over the rig at {device} from {held.holder}")
        lock = acquire(take_over=True)
        (say or _say)(f"quadtank: took the rig at {device} over from {held.holder} (pid {held.pid}); "
                      "waiting for that program to stop ...")
        deadline = time.monotonic() + TAKE_OVER_WAIT
        while pid_alive(held.pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        why = lock.lost()
        if pid_alive(held.pid) or why is not None:  # it did not yield (its lab's rules): never both drive
            lock.release()
            raise UsageError(f"the holder refused the take-over: {held.holder} (pid {held.pid}) still drives "
                             f"the rig at {device} after {TAKE_OVER_WAIT:g} s" + (f" ({why})" if why else "")
                             + "; this program did not touch it")
    hold = DaqHold(lock)
    try:
        yield hold
    finally:
        hold.close()


def _say(line: str) -> None:
    try:
        print(line, file=sys.stderr, flush=True)
    except OSError:
        pass


# --- quadtank lab [policy] ------------------------------------------------------------------

def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "lab", help="the lab configuration in use: administrators, runtime folder, unattended policy",
        description="Print the lab configuration in use (the file, the administrators' group, "
        "whether you are one, the runtime folder, the unattended policy).  `quadtank lab policy` "
        "sets the unattended policy in the lab file (administrators only); `quadtank lab init` makes the "
        "lab's runtime folder (administrators, once).")
    p.add_argument("--lab", metavar="FILE", help="the lab file (default: $QUADTANK_LAB, else "
                   "/etc/quadtank/lab.yaml)")
    p.set_defaults(handler=cmd_lab)
    labsub = p.add_subparsers(dest="lab_command", metavar="ACTION")
    pol = labsub.add_parser("policy", help="set what an unattended Active session does (administrators)",
                            description="Set the unattended policy in the lab file: an Active session "
                            "nobody is attached to keeps running while its log is written "
                            "(--keep-while-logging) and for --grace minutes after, then pauses "
                            "with the pumps at 0.")
    pol.add_argument("--keep-while-logging", choices=("yes", "no"), help="keep running while a log is written")
    pol.add_argument("--grace", metavar="MINUTES", type=float, help="minutes it keeps running after "
                     "the last client left (0..1440)")
    pol.set_defaults(handler=cmd_lab_policy)
    ini = labsub.add_parser("init", help="make the lab's shared runtime folder (an administrator, once)",
                            description="Make FOLDER (default: the lab file's runtime_dir, else "
                            "$QUADTANK_RUNTIME, else /tmp/quadtank-sessions) the lab's runtime folder: root's, "
                            "1755, with users/ (each user's folder of sessions), locks/ (the DAQ locks) and "
                            "bookings/, root's, 1777 sticky.  Run once at installation, by root or an administrator; "
                            "again to repair it.")
    ini.add_argument("folder", metavar="FOLDER", nargs="?", help="the folder to make the lab's runtime folder")
    ini.set_defaults(handler=cmd_lab_init)


def cmd_lab(args: argparse.Namespace) -> int:
    from quadtank_tui.session import roles
    from quadtank_tui.session.lab import lab_file_path, load_lab_config
    from quadtank_tui.session.policy import describe

    lab = load_lab_config(args.lab)
    me = roles.current_user()
    file = str(lab.source) if lab.source is not None else f"none ({lab_file_path(args.lab)[0]} not found: defaults)"
    admin = "yes" if roles.is_administrator(me.uid, lab) else "no"
    print(f"lab file        {file}")
    print(f"administrators  {roles.who_administers(lab)}")
    print(f"you             {me.user} (uid {me.uid}), administrator: {admin}")
    print(f"runtime dir     {_runtime_line(lab)}")
    print(f"sessions shared {'with group ' + lab.share_group if lab.share_group else 'with nobody (owner and administrators)'}")
    print(f"defaults        {lab.default_par}")
    p = lab.unattended
    print(f"unattended      keep_while_logging: {'yes' if p.keep_while_logging else 'no'}, "
          f"grace_minutes: {p.grace_minutes:g}")
    print(f"                {describe(p, active=True)}")
    print(f"                {describe(p, active=False)}")
    return 0


def _runtime_line(lab: LabConfig) -> str:
    """The runtime folder in force, and whether it is the lab's (shared) or the user's own."""
    from quadtank_tui.session.folders import RuntimeFolderError
    from quadtank_tui.session.lab import ensure_runtime_dir

    if lab.runtime_source != "default" and not os.path.lexists(lab.runtime_dir):  # not made by looking at it
        if lab.runtime_source == "lab file":
            return f"{lab.runtime_dir} (not there yet: an administrator makes it with `quadtank lab init`)"
        return f"{lab.runtime_dir} (not there yet: your first program makes it, yours alone)"
    try:
        root = ensure_runtime_dir(lab)
    except RuntimeFolderError as exc:
        return f"{lab.runtime_dir}: unusable: {exc}"
    if root.lab:
        return f"{root.path} (the lab's: sessions in {root.users}/UID, locks in {root.locks})"
    if root.note:
        return (f"{root.path}, yours alone: {root.note}; your sessions and rig locks are seen by nobody else "
                "until an administrator runs `quadtank lab init`")
    return f"{root.path}, yours alone (made by you: no other user's program trusts it)"


def cmd_lab_init(args: argparse.Namespace) -> int:
    from quadtank_tui.session import roles
    from quadtank_tui.session.folders import RuntimeFolderError, init_lab_folder
    from quadtank_tui.session.lab import load_lab_config

    lab = load_lab_config(args.lab)
    me = roles.current_user()
    if me.uid != 0:
        roles.require_administrator(me.uid, lab, "making the lab's runtime folder")
    folder = Path(args.folder).absolute() if args.folder else lab.runtime_dir.absolute()
    try:
        for line in init_lab_folder(folder):
            print(line)
    except (RuntimeFolderError, OSError) as exc:
        raise UsageError(f"{folder}: cannot make the lab's runtime folder: {exc.strerror or exc}"
                         if not isinstance(exc, RuntimeFolderError) else str(exc)) from None
    if folder != lab.runtime_dir.absolute():
        print(f"the lab uses {lab.runtime_dir}: put `runtime_dir: {folder}` in the lab file "
              f"({lab.source or '/etc/quadtank/lab.yaml'}) so that every program uses this one")
    return 0


def cmd_lab_policy(args: argparse.Namespace) -> int:
    from quadtank_tui.files.atomic import atomic_write_text
    from quadtank_tui.session import roles
    from quadtank_tui.session.lab import lab_file_path, load_lab_config, parse_lab_config, with_policy
    from quadtank_tui.session.policy import UnattendedPolicy, describe

    if args.keep_while_logging is None and args.grace is None:
        raise UsageError("give --keep-while-logging yes|no and/or --grace MINUTES")
    lab = load_lab_config(args.lab)
    roles.require_administrator(roles.current_user().uid, lab, "setting the unattended policy")
    old = lab.unattended
    try:
        policy = UnattendedPolicy(
            old.keep_while_logging if args.keep_while_logging is None else args.keep_while_logging == "yes",
            old.grace_minutes if args.grace is None else args.grace)
    except ValueError as exc:
        raise UsageError(str(exc).replace("grace_minutes", "--grace")) from None
    path = lab.source if lab.source is not None else lab_file_path(args.lab)[0]
    text = path.read_text(encoding="utf-8") if lab.source is not None else ""
    new = with_policy(text, policy)
    parse_lab_config(new, name=str(path), source=path)  # what is written must read back
    try:
        if lab.source is None:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(path, new, encoding="utf-8")
    except OSError as exc:
        raise UsageError(f"{path}: cannot write the lab file: {exc.strerror or exc}; an administrator "
                         "needs write access to it (or name another file with $QUADTANK_LAB)") from None
    print(f"{path}: unattended policy set")
    print(describe(policy, active=True))
    return 0
