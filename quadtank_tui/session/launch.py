"""Starting a session process detached from the terminal, and its `main`.

The launcher (the `quadtank` the user typed) reads and checks the files first, so a
bad `.par` is refused in the terminal with the usual message; then it starts
``python -m quadtank_tui.session.launch`` in a new session (no controlling terminal:
a hang-up, a closed tmux window, Ctrl-C in the launcher's terminal never reach it),
hands it the checked engine spec on its stdin (our own child: a pickle is fine
there, never on the socket), and waits on a pipe for "ready" with the session's
record, or "failed" with why.  The session's stdout and stderr go to
`<runtime>/<id>.out`, whose last line says why it stopped; it is kept with the
session's ended record (runtime.ENDED_KEPT).

A private session (`quadtank --no-session`) is the same process and protocol for
one terminal: its socket, record and output live in a folder of its own (mode 0700)
that `quadtank sessions` does not list, only its owner may connect, and it ends
with the `quadtank` that started it - by that one's StopSession on Exit, or, when
that process dies any way at all (killed, its terminal gone), by its lifeline: a
pipe whose only writer is the launcher, read to its end by the session.  The rig's
lock stays with the launcher, which watches it as the screen's own.
"""

from __future__ import annotations

import json
import os
import pickle
import shutil
import subprocess
import tempfile
import sys
import threading
import time
from dataclasses import asdict, dataclass, replace
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from quadtank_tui.session.info import SessionInfo

if TYPE_CHECKING:  # the launcher spawns the session before it loads the engine
    from quadtank_tui.engine.runner import ClockKind, EngineSpec
    from quadtank_tui.files.script import Script
    from quadtank_tui.session.riglock import RigLock

#: Seconds a session may take to start (a fresh interpreter importing numpy).
START_TIMEOUT = 60.0


class SessionStartError(OSError):
    """The session process did not start; the message says why."""


@dataclass(frozen=True)
class HeadlessArgs:
    """`quadtank run ... --detach`: the run's options, checked by the launcher."""

    par: str | None
    script: Script | None
    duration: float
    out: str
    seed: int | None
    clock: ClockKind
    speed: float | None
    params_dir: str = "params"


@dataclass(frozen=True)
class SessionSpec:
    """What a session process is started with: an engine for the TUI, or a
    headless run (`run`)."""

    engine: EngineSpec | None
    runtime: str
    daq_config: str | None = None
    run: HeadlessArgs | None = None
    #: One terminal's own session (`--no-session`): unlisted, its owner's only, it
    #: ends with its launcher (see the module's docstring).
    private: bool = False


class Spawned:
    """A session process started before its spec is known: it boots (a fresh
    interpreter importing numpy and the engine, about 0.3 s) while the launcher
    checks the files and loads the UI, then waits on its stdin for the spec.
    `send` hands it over and waits for "ready"; `cancel` ends it unseen (it
    reads an empty spec and exits without a record).

    private : the process is given the read end of a lifeline whose write end only
        this process holds (`let_go` closes it; so does this process's end)."""

    def __init__(self, *, private: bool = False) -> None:
        r, w = os.pipe()
        life_r, self._lifeline = os.pipe() if private else (-1, -1)
        passed = (w, life_r) if private else (w,)
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-m", "quadtank_tui.session.launch", *map(str, passed)],
                stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                pass_fds=passed, start_new_session=True, close_fds=True,
            )
        except OSError:
            os.close(r)
            self.let_go()
            raise
        finally:
            os.close(w)
            if life_r >= 0:
                os.close(life_r)
        self._ready = r
        self._handed_over = False
        # Reap it whenever it ends, so a session that stops while we run is no zombie.
        threading.Thread(target=self._proc.wait, name="quadtank-session-reaper", daemon=True).start()

    @property
    def pid(self) -> int:
        return self._proc.pid

    def send(self, spec: SessionSpec, *, lock: RigLock | None = None,
             timeout: float = START_TIMEOUT) -> SessionInfo:
        """Start the session `spec` describes; its record once it listens."""
        self.hand_over(spec, lock=lock)
        return self.wait_ready(timeout)

    def hand_over(self, spec: SessionSpec, *, lock: RigLock | None = None) -> None:
        """Give the process its spec (it goes on booting meanwhile).  `lock`: the
        rig's lock this launcher took (`quadtank --daq`), handed to the session
        process, which holds it from then on."""
        proc = self._proc
        if lock is not None:
            try:
                lock.transfer(proc.pid)  # before the process looks: it adopts the lock
            except OSError:
                proc.kill()
                self._close_ready()
                raise
        self._handed_over = True
        try:
            assert proc.stdin is not None
            proc.stdin.write(pickle.dumps(spec))
            proc.stdin.close()
        except BrokenPipeError:
            pass  # it died booting: wait_ready says so

    def wait_ready(self, timeout: float = START_TIMEOUT) -> SessionInfo:
        """The session's record once it listens, or SessionStartError saying why not."""
        proc = self._proc
        try:
            reply = _read_reply(self._ready, timeout)
        finally:
            self._close_ready()
        if reply.startswith(b"ready "):
            return SessionInfo(**json.loads(reply[6:]))
        if reply.startswith(b"failed "):
            raise SessionStartError(reply[7:].decode(errors="replace").strip())
        if proc.poll() is None:
            proc.kill()
        raise SessionStartError(f"the session process did not start (exit code {proc.poll()})")

    def cancel(self) -> None:
        """End the process: before it was handed a spec (the files were refused) it
        reads an empty one and exits; after, the session stops as with `quadtank
        stop` (nobody would know it runs): asked to, if it already said ready, else
        by itself when it finds nobody listening for its "ready"."""
        if self._handed_over:
            self._stop_handed_over()
        else:
            try:
                if self._proc.stdin is not None:
                    self._proc.stdin.close()  # an empty spec: it exits at once
            except OSError:
                pass
        self._close_ready()
        self.let_go()

    def _stop_handed_over(self) -> None:
        if self._ready < 0:
            return
        import select

        reply = b""
        if select.select([self._ready], [], [], 0)[0]:
            reply = os.read(self._ready, 65536)
        self._close_ready()
        if reply.startswith(b"ready "):
            from quadtank_tui.session.client import SessionError, stop_session_at

            try:
                info = SessionInfo(**json.loads(reply[6:]))
                stop_session_at(info.socket, expect=info)
            except (SessionError, OSError, ValueError):
                self._proc.terminate()

    def _close_ready(self) -> None:
        if self._ready >= 0:
            os.close(self._ready)
            self._ready = -1

    def let_go(self) -> None:
        """Close the lifeline: a private session stops (pumps at 0) on its own."""
        if self._lifeline >= 0:
            os.close(self._lifeline)
            self._lifeline = -1

    def wait_ended(self, timeout: float) -> bool:
        """Whether the process has exited within `timeout` s."""
        try:
            self._proc.wait(timeout)
        except subprocess.TimeoutExpired:
            return False
        return True


def start_session(spec: SessionSpec, *, lock: RigLock | None = None,
                  timeout: float = START_TIMEOUT) -> SessionInfo:
    """Start a detached session process; its record once it listens.  `lock`: the
    rig's lock this launcher took (`quadtank --daq`), handed to the session process,
    which holds it from then on."""
    return Spawned().send(spec, lock=lock, timeout=timeout)


def _read_reply(fd: int, timeout: float) -> bytes:
    import select

    out = b""
    end = time.monotonic() + timeout
    while True:
        left = end - time.monotonic()
        if left <= 0:
            return out
        ready, _, _ = select.select([fd], [], [], left)
        if not ready:
            return out
        chunk = os.read(fd, 65536)
        if not chunk:
            return out
        out += chunk


# --- the session process -----------------------------------------------------------------------


def session_main(ready_fd: int, lifeline: int = -1) -> int:
    """Build the engine, take the DAQ's lock, listen, say ready, serve until stopped.
    `lifeline`: a private session's (its launcher's end closing stops it)."""
    from quadtank_tui.engine.runner import assemble
    from quadtank_tui.session.host import Access, SessionHost
    from quadtank_tui.session.lab import load_lab_config
    from quadtank_tui.session.riglock import RigLock
    from quadtank_tui.session.roles import user_name
    from quadtank_tui.session.runtime import claim_id, out_path as output_of, remove_files, runtime_dir, socket_path, \
        write_record
    from quadtank_tui.session.server import listen

    data = sys.stdin.buffer.read()
    if not data:  # Spawned.cancel: the launcher refused the files; nothing to do
        return 0
    spec: SessionSpec = pickle.loads(data)
    ready = os.fdopen(ready_fd, "wb", buffering=0)
    from quadtank_tui.session.folders import own_place

    lab = replace(load_lab_config(), runtime_dir=Path(spec.runtime), runtime_source="named")
    runtime = own_place(runtime_dir(lab.runtime_dir))  # this user's place: nobody else writes in it
    if spec.private:  # a folder of its own, unlisted, its owner's only; gone with the session
        runtime = Path(tempfile.mkdtemp(prefix="private-", dir=runtime))
    uid = os.getuid()
    sid = claim_id(runtime, user_name(uid))
    out_path = output_of(runtime, sid)
    lock: RigLock | None = None
    slots = None
    try:
        _redirect_stdio(out_path)
        daq = None
        if spec.daq_config is not None:
            from quadtank_tui.daq.open import open_daq

            if spec.engine is not None:
                wired = spec.engine.params.process_plant()
            else:  # the DAQ is wired for the plant of the run's parameters
                from quadtank_tui.engine.runner import load_parameters
                from quadtank_tui.files.par import ParStore

                assert spec.run is not None
                wired = load_parameters(spec.run.par, ParStore(spec.run.params_dir))[0].process_plant()
            daq = open_daq(spec.daq_config, wired)  # no warning: the launcher said it; the record says it
            assert daq is not None
            if not spec.private:  # a private session's launcher keeps the lock (and watches it)
                # under the rig's identity (a Modbus rig's addresses, a serial rig's device); adopts the launcher's
                lock = RigLock.of(daq.config, lab, session=sid)
            from quadtank_tui.session.bookings import SlotWatch
            from quadtank_tui.session.riglock import rig_keys

            slots = SlotWatch(lab, lock.keys if lock is not None else rig_keys(daq.config), uid)
            if (booked := slots.refusal()) is not None:
                raise PermissionError(booked.replace("; Active needs", "; a session on the rig needs"))
        scripted = None
        if spec.run is not None:
            from quadtank_tui.engine.headless import prepare_headless
            from quadtank_tui.session.scripted import ScriptedRun

            r = spec.run
            prepared = prepare_headless(par=r.par, script=r.script, duration=r.duration, out=Path(r.out),
                                        seed=r.seed, clock=r.clock, speed=r.speed,
                                        params_dir=Path(r.params_dir), daq=daq)
            engine, scripted = prepared.engine, ScriptedRun(prepared)
        else:
            assert spec.engine is not None
            engine = assemble(spec.engine, daq=daq)
        sock_path = socket_path(runtime, sid)
        # Every local user may connect and the session checks each one (Access):
        # a mode of 0660 with the share or admin group shut out a teacher outside
        # that group, and the group could not be set at all by an owner outside it.
        listener = listen(str(sock_path), anyone=not spec.private)
        params = engine.params
        plant = params.process.kind if params.process is not None else "quadtank"
        info = SessionInfo(id=sid, owner=user_name(uid), uid=uid, pid=os.getpid(),
                           started=datetime.now().isoformat(timespec="seconds"), plant=plant,
                           socket=str(sock_path), cwd=os.getcwd(), daq=spec.daq_config or "",
                           headless=scripted is not None,
                           watchdog="" if daq is None else "device" if daq.config.watchdog else "none")
        access = Access(uid, is_admin=lambda peer: False) if spec.private else Access.for_lab(uid, lab)
        host = SessionHost(engine, listener, info, runtime=runtime, access=access,
                           policy=lab.unattended, scripted=scripted, slots=slots)
        host.install_signal_handlers()
        if lifeline >= 0:
            threading.Thread(target=_hold_on, args=(lifeline, host.request_stop), name="quadtank-lifeline",
                             daemon=True).start()
        if lock is not None:  # an administrator may take the rig over: then stop, pumps at 0
            from quadtank_tui.session.lockwatch import LockWatch

            LockWatch(lock, lambda why: host.request_stop(f"the rig was taken over: {why}")).start()
        write_record(runtime, info)
    except BaseException as exc:  # noqa: BLE001 - the launcher says why
        if lock is not None:
            lock.release()
        remove_files(runtime, sid, output=True)  # it never ran: the launcher says why
        if spec.private:
            shutil.rmtree(runtime, ignore_errors=True)
        ready.write(f"failed {exc}".encode())
        ready.close()
        return 1
    try:
        ready.write(b"ready " + json.dumps(asdict(info)).encode())
        ready.close()
    except OSError:  # the launcher was interrupted before the session was ready
        host.request_stop("its launcher went away before it was ready")
    try:
        reason = host.serve()
    finally:
        if lock is not None:
            lock.release()  # after the pumps went to 0
    # The reason is in the record too (SessionHost); here it is the output's last line.
    print(f"{datetime.now():%Y-%m-%d %H:%M:%S} session {sid} stopped: {reason}", flush=True)
    if spec.private:  # its client heard why (Ended); nobody else will look
        shutil.rmtree(runtime, ignore_errors=True)
    return 0


def _hold_on(lifeline: int, stop: Callable[[str], None]) -> None:
    """Wait for the lifeline's end (its launcher closed it, or exited, killed or not),
    then stop the session: pumps at 0, log kept."""
    try:
        while os.read(lifeline, 512):
            pass
    except OSError:
        pass
    stop("its terminal's quadtank ended")


def _redirect_stdio(out_path: Path) -> None:
    fd = os.open(out_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    null = os.open(os.devnull, os.O_RDONLY)
    os.dup2(null, 0)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    os.close(null)


if __name__ == "__main__":  # pragma: no cover - the session process
    raise SystemExit(session_main(*map(int, sys.argv[1:3])))
