"""The engine in a process of its own, behind the same EngineHandle.

In one process the loop's thread shares the interpreter lock with the UI: while the
UI builds a chart the loop's wake-up waits for the lock, and its p99 jitter at 50 ms
was 5-8 ms (benchmarks/loop_timing.py).  Here the loop runs in a child process
(started with "spawn": a fresh interpreter, no inherited threads), so its timing
does not depend on what the UI does.

- The parent reads files and checks them (``runner.engine_spec``), so a bad `.par` is
  refused with the same message as in-process, before any process starts.
- Commands go down a pipe as typed messages (:mod:`engine.messages`); the child applies each between samples and sends the
  CommandResult back, which resolves the parent's Future.  Before the result is
  sent, the snapshot that shows the command's effect is published.
- Snapshots and ring buffers come up through shared memory (:mod:`engine.shared`),
  written without locks: no reader can hold the loop up.  The log's rows and every
  save go to the loop's writer thread (:mod:`engine.filework`): no disk holds it up
  either; a command with file work is answered when that work is done.
- The child stops the loop, pumps to 0, if the parent goes away (its end of the
  pipe closes: crash, kill, lost SSH session), or on SIGTERM or SIGHUP.  It ignores
  SIGINT: Ctrl-C in a terminal reaches the whole process group, and the parent
  decides how to stop.  If the child dies, the parent's snapshot says so and new
  commands are refused.
"""

from __future__ import annotations

import functools
import multiprocessing
import os
import signal
import threading
from concurrent.futures import Future
from dataclasses import replace
from multiprocessing.connection import wait
from typing import Any, Callable


from quadtank_tui.core.parameters import Parameters
from quadtank_tui.engine.backend import ProcessBackend
from quadtank_tui.engine.client_side import HeldLocally
from quadtank_tui.engine.commands import Command, CommandResult
from quadtank_tui.engine.messages import (
    Failed, FromLoop, MessageError, Ready, Result, Start, Stop, Stopped, Submit, from_loop, to_loop,
)
from quadtank_tui.engine.runner import Engine, EngineSpec, assemble
from quadtank_tui.engine.shared import SharedState, SnapshotReader, SnapshotWriter
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.files.par import ParStore

#: How long the child may take to import and build its engine.
START_TIMEOUT = 60.0
#: How long stop() waits for the child to put the pumps at 0 and close its log.
STOP_TIMEOUT = 10.0


class EngineProcessError(OSError):
    """The loop process could not be started; the message says why (an OSError, like
    the other failures of the system around the program)."""


class _StopRequest:
    """SIGTERM / SIGHUP in the loop process: a flag, and a byte on a pipe the main
    thread waits on with the parent's messages.  (A handler that raised could cut a
    shared-memory write, or the stop itself, in half.)"""

    def __init__(self) -> None:
        self.reason: str | None = None
        self.fd, self._wake = os.pipe()
        os.set_blocking(self._wake, False)
        for sig in (signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, self._handle)

    def _handle(self, signum: int, frame: object) -> None:
        self.reason = signal.Signals(signum).name
        try:
            os.write(self._wake, b"!")
        except OSError:
            pass


def _child_main(spec: EngineSpec, shared_path: str, inbox: Any, outbox: Any,
                daq_factory: Callable[[], ProcessBackend] | None,
                setup: Callable[[Engine], None] | None) -> None:
    """The loop process: build the engine, then serve the parent's messages until
    told to stop, a stop signal, or the parent's end of the pipe closing."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    stop = _StopRequest()
    engine: Engine | None = None
    try:
        shared = SharedState.attach(shared_path, spec.history_capacity)
        shared.block.unlink()  # mapped on both sides now (and gone if the parent died)
        engine = assemble(spec, daq=daq_factory() if daq_factory is not None else None)
        engine.loop.attach_history(shared.history)
        writer = SnapshotWriter(shared)
        engine.loop.subscribe(writer)
        if setup is not None:
            setup(engine)
        engine.loop.publish()
        writer.flush()
        outbox.send(Ready(engine.loop.defaults))
    except BaseException as exc:  # noqa: BLE001 - tell the parent why, whatever it was
        try:
            outbox.send(Failed(f"{type(exc).__name__}: {exc}"))
        except (OSError, ValueError):
            pass
        if engine is not None:
            engine.stop()  # a DAQ link it opened is closed, pumps at 0
        return
    crash: str | None = None
    send_lock = threading.Lock()

    def send(message: FromLoop) -> None:
        with send_lock:
            outbox.send(message)

    def answer(command_id: int, fut: Future[CommandResult]) -> None:
        # In the loop's thread, between samples: the snapshot showing the command's
        # effect goes out before the result.
        writer.flush()
        try:
            send(Result(command_id, fut.result()))
        except (OSError, ValueError):
            pass  # the parent is gone; the main thread sees it too

    try:
        # This thread never waits for a command's result, so a stop (or the parent
        # going away) is seen at once, even while a sample hangs on a silent device.
        while stop.reason is None:
            wait([inbox, stop.fd])
            if stop.reason is not None:
                break
            try:
                message = to_loop(inbox.recv())
            except (EOFError, OSError):
                break  # the parent is gone: stop, pumps at 0
            if isinstance(message, Start):
                engine.start()
            elif isinstance(message, Submit):
                engine.submit(message.command).add_done_callback(functools.partial(answer, message.id))
            else:
                break
    except Exception as exc:  # noqa: BLE001 - stop in order and say why
        crash = f"{type(exc).__name__}: {exc}"
    finally:
        engine.stop()  # commands still queued are refused: the user asked to stop
        writer.flush()
        try:
            send(Stopped(engine.crash or crash))
        except (OSError, ValueError):
            pass


class EngineProcess(HeldLocally):
    """Implements :class:`quadtank_tui.engine.handle.EngineHandle` with the loop in a
    child process: ``EngineProcess(engine_spec(...))`` is ``build_engine(...)``'s
    engine, built ready to read (start-up state, not running); :meth:`start` starts
    the sampling.

    daq_factory : builds the DAQ backend, in the child (a backend holds locks and
        sockets, which do not cross processes) and, should the child be killed, here
        to put the pumps at 0; e.g. ``functools.partial(ModbusBackend, config)``
    setup : called in the child with the engine before it is published (benchmarks
        and tests); must be picklable, i.e. a module-level function or a partial.
    """

    def __init__(self, spec: EngineSpec, *, daq_factory: Callable[[], ProcessBackend] | None = None,
                 setup: Callable[[Engine], None] | None = None) -> None:
        if spec.clock == "manual":
            raise ValueError("a manual clock is stepped by hand: use build_engine")
        self.warnings = spec.warnings
        self.crash: str | None = None
        #: What the parent did about the pumps after the child died (for the fault line).
        self.rescue: str | None = None
        self._daq_factory = daq_factory
        self._store = ParStore(spec.params_dir)
        self._logs_dir = spec.logs_dir
        self._shared: SharedState | None = SharedState.create(spec.history_capacity)
        self._history = self._shared.history
        self._reader: SnapshotReader | None = SnapshotReader(self._shared)
        self._read_lock = threading.Lock()
        self._send_lock = threading.Lock()
        self._futures: dict[int, Future[CommandResult]] = {}
        self._next_id = 0
        self._started = False
        self._stopping = False
        self._stopped = False
        self._gone = threading.Event()  # the child's pipe closed
        ctx = multiprocessing.get_context("spawn")
        child_inbox, self._inbox = ctx.Pipe(duplex=False)
        self._outbox, child_outbox = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(
            target=_child_main, name="quadtank-loop", daemon=True,
            args=(spec, self._shared.block.path, child_inbox, child_outbox, daq_factory, setup),
        )
        try:
            try:
                self._proc.start()
            finally:
                child_inbox.close()
                child_outbox.close()
            reply = self._receive_first()
        finally:
            self._shared.block.unlink()  # both processes have it mapped (or the child failed)
        if not isinstance(reply, Ready):
            self._proc.join(timeout=STOP_TIMEOUT)
            self._release()
            why = reply.reason if isinstance(reply, Failed) else f"it answered {type(reply).__name__}"
            raise EngineProcessError(f"the control loop process did not start: {why}")
        self._defaults: Parameters = reply.defaults
        snap = self._reader.read()
        assert snap is not None  # the child published before it said ready
        self._snap: Snapshot = snap
        self._listener = threading.Thread(target=self._listen, name="quadtank-loop-results", daemon=True)
        self._listener.start()

    def _receive_first(self) -> FromLoop:
        if not self._outbox.poll(START_TIMEOUT):
            self._proc.kill()
            return Failed(f"no answer within {START_TIMEOUT:g} s")
        try:
            return from_loop(self._outbox.recv())
        except (EOFError, OSError):
            self._proc.join(timeout=STOP_TIMEOUT)
            return Failed(f"it exited with code {self._proc.exitcode}")

    # --- the EngineHandle read side ------------------------------------------------------------

    def snapshot(self) -> Snapshot:
        with self._read_lock:
            if self._reader is not None:
                gone = self._gone.is_set()
                self._snap = self._reader.read() or self._snap
                if gone:  # nothing will write again: one last read, then keep it
                    self._reader = None
            snap = self._snap
        if self._gone.is_set() and not self._stopping and snap.fault is None:
            self._proc.join(timeout=0.5)
            why = self.crash or f"exit code {self._proc.exitcode}"
            pumps = f"; {self.rescue}" if self.rescue else ""
            return replace(snap, state="Pause", fault=f"the control loop process stopped unexpectedly "
                           f"({why}){pumps}; restart the program")
        return snap

    @property
    def running(self) -> bool:
        """The loop samples (started, and its process is alive)."""
        return self._started and not self._gone.is_set()

    # --- the one write door -----------------------------------------------------------------

    def submit(self, command: Command) -> Future[CommandResult]:
        """Send `command` to the loop; the Future resolves when it has been applied."""
        fut: Future[CommandResult] = Future()
        with self._send_lock:
            if self._stopping or self._gone.is_set():
                fut.set_result(CommandResult.refused("the engine has stopped"))
                return fut
            self._next_id += 1
            self._futures[self._next_id] = fut
            try:
                self._inbox.send(Submit(self._next_id, command))
            except (OSError, ValueError) as exc:
                self._futures.pop(self._next_id, None)
                fut.set_result(CommandResult.refused(f"the control loop process is gone ({exc})"))
        return fut

    def _listen(self) -> None:
        """Results up from the child until its end of the pipe closes."""
        while True:
            try:
                message = from_loop(self._outbox.recv())
            except (EOFError, OSError):
                break
            except MessageError:
                continue  # not ours to act on (a bug in the child): its next message may be
            if isinstance(message, Result):
                with self._send_lock:
                    fut = self._futures.pop(message.id, None)
                if fut is not None and not fut.done():
                    fut.set_result(message.result)
            elif isinstance(message, Stopped):
                self.crash = message.crash
        with self._send_lock:
            self._gone.set()
            unexpected = not self._stopping
            waiting, self._futures = list(self._futures.values()), {}
        for fut in waiting:
            if not fut.done():
                fut.set_result(CommandResult.refused("the engine has stopped"))
        if unexpected:
            self._pumps_to_zero()

    def _pumps_to_zero(self) -> None:
        """The loop process died (killed, out of memory) without its stop: command the
        rig's pumps to 0 over a link of our own."""
        if self._daq_factory is None:
            return
        try:
            backend = self._daq_factory()
            try:
                backend.safe_state()
            finally:
                backend.close()
            self.rescue = "the pumps were commanded to 0 from here"
        except Exception as exc:  # noqa: BLE001 - say it; the rig's watchdog is the last line
            self.rescue = f"the pumps could NOT be commanded to 0 ({type(exc).__name__}: {exc})"

    # --- lifetime ------------------------------------------------------------------------------

    def start(self) -> None:
        """Start sampling (idempotent)."""
        with self._send_lock:
            if self._started or self._stopping or self._gone.is_set():
                return
            self._started = True
            try:
                self._inbox.send(Start())
            except (OSError, ValueError):
                pass  # gone: the listener has seen it or will

    def stop(self) -> None:
        """Stop the loop, pumps to 0, logging stopped (rows kept); wait for the process
        to end.  The last snapshot and the trends stay readable.  Idempotent."""
        if self._stopped:
            return
        with self._send_lock:
            self._stopping = True
            try:
                self._inbox.send(Stop())
            except (OSError, ValueError):
                pass
        self._listener.join(timeout=STOP_TIMEOUT)
        self._proc.join(timeout=STOP_TIMEOUT)
        if self._proc.is_alive():
            self._proc.kill()
            self._proc.join()
            self._pumps_to_zero()
        self.snapshot()  # the last one the child published
        self._release()

    def _release(self) -> None:
        """Close the pipes and the process handle; keep a private copy of the trends
        and let the shared memory go."""
        self._stopped = True
        self._inbox.close()
        self._outbox.close()
        try:
            self._proc.close()
        except ValueError:  # still running after kill(): leave the handle to the GC
            pass
        with self._read_lock:
            self._reader = None
            self._history = self._history.copy()
            self._shared = None

    def __enter__(self) -> EngineProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
