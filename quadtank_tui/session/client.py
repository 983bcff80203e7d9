"""A TUI's (or a script's) handle on a session: the EngineHandle over its socket.

On attach the session sends everything - its whole ring buffer, the snapshot, the
defaults - before anything else, so the trends are complete (nothing sampled while
no client was attached is missing) and the screen is live at once: the client
returns once it holds the whole history (the Welcome and the HistoryPart lines
that follow it; the session encodes one per turn, so its sampling never waits).  Then a reader thread
appends each update's rows to a private copy of the ring buffer and keeps the newest
snapshot; `snapshot()` and `history()` read those, never the socket.  A screen
may take the reading over on its own event loop (`read_on`): then an update or a
command's answer reaches it with no thread in between; closing goes back to a
thread (the loop may be gone by then) to hear the session's last words.

Closing a client never stops the session (that is `stop_session`, or the Exit
window's "Stop the session").  If the session process dies without saying so (a
SIGKILL), the snapshot says so, the commands are refused, and - for an operator of
an Active session whose DAQ configuration it can read - the pumps are commanded to
0 over a link of its own; the guard and the rig's watchdog are the last lines.
A client the session dropped (it flooded, sent a line that is not a message, fell
too far behind) is told so (`Dropped`): the session runs on and keeps driving the
rig, so the screen says it was dropped and touches no pump.  A connection that
closes without a word while the session's process still answers on its socket is
taken the same way: only a session that is gone gets the rescue.

A private session's client (`private`, `quadtank --no-session`) is its session's
only screen: it offers no lab session (nothing to detach from), its close stops
the session, and then lets go of the session's lifeline (session/launch.py).
"""

from __future__ import annotations

import asyncio
import itertools
import os
import select
import socket
import threading
import time
from concurrent.futures import Future
from dataclasses import replace
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from quadtank_tui.core.parameters import Parameters
from quadtank_tui.engine.commands import Command, CommandResult
from quadtank_tui.engine.handle import LabSession
from quadtank_tui.engine.history import History
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.files.log_writer import log_path
from quadtank_tui.files.proc import pid_alive
from quadtank_tui.files.par import ParStore
from quadtank_tui.session.unixpath import unix_address
from quadtank_tui.session.protocol import (
    MAX_SESSION_LINE, Dropped, Ended, Hello, HistoryPart, LineReader, ProtocolError, Refused, Result, Role, Roster,
    SessionInfo, StopSession, Submit, Update, Welcome, decode, encode,
)

#: Seconds to connect and receive the Welcome (with the whole history: 3.5 MB).
ATTACH_TIMEOUT = 10.0
#: Seconds a session whose connection closed without a word is given to finish
#: exiting before it is believed alive: a SIGKILLed session's connections close
#: while its process still exits, and its listening socket may still accept for a
#: moment (a fresh-clone CI took a killed session for one that dropped its screen,
#: and so gave no rescue).
GONE_SETTLE = 1.0
#: Seconds `stop_session` waits for the session to stop (pumps at 0, log closed).
STOP_TIMEOUT = 15.0


class SessionError(OSError):
    """The session could not be reached, or refused us; the message says why."""


class SessionClient:
    """Implements :class:`quadtank_tui.engine.handle.EngineHandle` on a session, and
    :class:`~quadtank_tui.engine.handle.LabSession` on a lab session.

    path : the session's socket;  role : "operator" (drive it) or "observer"
    take_over : an administrator takes the operator's place
    private : the session is this client's own (it stops when this client closes);
        `let_go` is called once it has (the session's lifeline)
    expect : the session's record: the process answering on the socket must be its
        pid, running as its uid (SO_PEERCRED), or nothing is sent (`check_peer`)
    """

    def __init__(self, path: str | Path, *, role: Role = "operator", take_over: bool = False,
                 client: str = "tui", timeout: float = ATTACH_TIMEOUT, private: bool = False,
                 let_go: Callable[[], None] | None = None, expect: SessionInfo | None = None) -> None:
        self.warnings: tuple[str, ...] = ()
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.settimeout(timeout)
        try:
            connect(sock, path, timeout)
        except OSError as exc:
            sock.close()
            raise _unreachable(path, exc) from None
        try:
            check_peer(sock, path, expect)
        except SessionError:
            sock.close()
            raise
        self._sock = sock
        self._path = str(path)
        self._reader = LineReader(MAX_SESSION_LINE)
        self._pending: list[bytes] = []
        try:
            sock.sendall(encode(Hello(role, client, take_over)))
            first = self._next_message()
            parts = [self._next_message() for _ in range(first.parts)] if isinstance(first, Welcome) else []
        except (OSError, ProtocolError) as exc:
            sock.close()
            raise SessionError(f"the session at {path} did not answer: {exc}") from None
        if isinstance(first, Refused):
            sock.close()
            raise SessionError(first.reason)
        if not isinstance(first, Welcome) or not all(isinstance(p, HistoryPart) for p in parts):
            sock.close()
            what = type(first).__name__ if not isinstance(first, Welcome) else "a Welcome without its history"
            raise SessionError(f"the session at {path} answered {what}, not Welcome")
        sock.settimeout(None)
        w = first
        self.info: SessionInfo = w.info
        self.role: Role = w.role
        self.controller = w.controller
        self._policy = (w.policy_simul, w.policy_active)
        self.clients = w.info.clients
        self._defaults = w.defaults
        self._params: Parameters = w.snapshot.params
        self._snap: Snapshot = w.snapshot
        self._history = History(w.capacity)
        for part in parts:
            self._history.extend(part.rows)
        self._store = ParStore(w.params_dir)
        self._logs_dir = Path(w.logs_dir)
        self._ids = itertools.count(1)
        self._futures: dict[int, Future[CommandResult]] = {}
        self._lock = threading.Lock()
        self._send_lock = threading.Lock()
        self._gone = threading.Event()
        self._finished = False   # _finish ran (once: the thread or the screen's loop)
        self._closing = False
        #: Who reads the socket: the thread, or (read_on) an event loop; one at a time
        #: reads under _read_lock, so a handover in either direction loses nothing.
        self._read_lock = threading.Lock()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._wake_r, self._wake_w = os.pipe()
        self.ended: str | None = None       # the session's own reason, when it stopped in order
        self.dropped: str | None = None     # why the session dropped this client (it runs on)
        self.rescue: str | None = None
        self.private = private
        self._let_go = let_go
        #: What Exit chose: stop the session when this client closes (else detach).
        self.stop_on_close = private
        self._thread = threading.Thread(target=self._listen, name="quadtank-session-client", daemon=True)
        self._thread.start()

    def _next_message(self) -> Any:
        """The session's next message, while attaching (blocking)."""
        while not self._pending:
            data = self._sock.recv(1 << 20)
            if not data:
                raise ProtocolError("it closed the connection")
            self._pending = self._reader.feed(data)
        return decode(self._pending.pop(0))

    # --- EngineHandle ------------------------------------------------------------------------

    def snapshot(self) -> Snapshot:
        snap = self._snap
        why = self._gone_reason()
        if why is None:
            return snap
        # Dropped, this screen no longer sees the session, which still runs: its last state stays.
        return replace(snap, fault=why) if self.dropped is not None else replace(snap, state="Pause", fault=why)

    def _gone_reason(self) -> str | None:
        """Why the session is no longer there (None while it is, or after we left)."""
        if not self._gone.is_set() or self._closing:
            return None
        if self.ended is not None:
            return f"session {self.info.id} ended: {self.ended}"
        if self.dropped is not None:
            return (f"session {self.info.id} dropped this screen ({self.dropped}) and runs on: "
                    f"quadtank attach {self.info.id} comes back to it")
        snap = self._snap
        pumps = f"; {self.rescue}" if self.rescue else \
            ("; the rig's watchdog puts its pumps at 0" if snap.operation == "Active" else "")
        return (f"the session process {self.info.id} (pid {self.info.pid}) stopped unexpectedly"
                f"{pumps}; its log so far is in {self._logs_dir}")

    def submit(self, command: Command) -> Future[CommandResult]:
        fut: Future[CommandResult] = Future()
        if self.role != "operator":
            fut.set_result(CommandResult.refused(f"read-only: you observe session {self.info.id}; "
                                                 f"{self.controller}"))
            return fut
        with self._lock:
            if self._gone.is_set():
                fut.set_result(CommandResult.refused(f"session {self.info.id} is gone"))
                return fut
            cid = next(self._ids)
            self._futures[cid] = fut
        try:
            self._send(Submit(cid, command))
        except OSError as exc:
            with self._lock:
                self._futures.pop(cid, None)
            fut.set_result(CommandResult.refused(f"session {self.info.id} is gone ({exc})"))
        return fut

    def _send(self, message: Any) -> None:
        with self._send_lock:
            self._sock.sendall(encode(message))

    def history(self, seconds: float | None = None) -> Mapping[str, np.ndarray]:
        return self._history.last(seconds)

    def defaults(self) -> Parameters:
        return self._defaults

    def par_names(self) -> list[str]:
        return self._store.names()

    def log_exists(self, name: str) -> bool:
        return log_path(self._logs_dir, name).exists()

    @property
    def logs_dir(self) -> Path:
        """The session's logs folder (the ghost run's window lists it)."""
        return Path(self._logs_dir)

    def lab_session(self) -> LabSession | None:
        """This client's lab session; None for a private one (nothing to detach from)."""
        return None if self.private else self

    # --- LabSession ------------------------------------------------------------------------------

    @property
    def session_id(self) -> str:
        return self.info.id

    @property
    def started(self) -> str:
        return self.info.started

    @property
    def operating(self) -> bool:
        return self.role == "operator"

    def stop_on_exit(self) -> None:
        self.stop_on_close = True

    # --- the session's side ----------------------------------------------------------------------

    @property
    def policy(self) -> str:
        """What the session will do once no operator is attached (its lab's policy)."""
        return self._policy[self._snap.operation == "Active"]

    @property
    def gone(self) -> bool:
        """The connection is closed (the session ended, died, or we detached)."""
        return self._gone.is_set()

    def wait_gone(self, timeout: float | None = None) -> bool:
        return self._gone.wait(timeout)

    def session_banner(self) -> str:
        """One line for the screen: whose session this is and who drives it - or,
        once it is gone, why (the status line's fault is cut on a narrow screen)."""
        why = self._gone_reason()
        if why is not None:
            return f"{why}; the screen shows its last state, q leaves"
        you = "you operate it" if self.role == "operator" else "read-only: you observe it"
        return f"session {self.info.id} of {self.info.owner}: {self.controller}; {you}"

    def _listen(self) -> None:
        """The reader thread: until the session hangs up, or `read_on` hands the
        reading to an event loop (a byte on the wake pipe)."""
        with self._read_lock:
            lines, self._pending = self._pending, []
            ok = self._act_on(lines)
        while ok:
            try:
                ready, _, _ = select.select([self._sock.fileno(), self._wake_r], [], [])
            except (OSError, ValueError):
                break
            if self._wake_r in ready:
                return  # handed over: the loop reads from here on
            with self._read_lock:
                ok = self._receive()
        self._finish()

    def _receive(self) -> bool:
        """Act on what the socket holds now; False once the session hung up."""
        try:
            data = self._sock.recv(1 << 20, socket.MSG_DONTWAIT)
        except (BlockingIOError, InterruptedError):
            return True  # the other reader of a handover took it
        except OSError:
            return False
        if not data:
            return False
        try:
            lines = self._reader.feed(data)
        except ProtocolError:
            return False
        return self._act_on(lines)

    def _act_on(self, lines: list[bytes]) -> bool:
        try:
            for line in lines:
                self._handle(decode(line))
        except ProtocolError:
            return False
        return True

    def _finish(self) -> None:
        """The session hung up (or we did): the commands still waiting are refused;
        an Active session that died without a word gets its pumps put at 0."""
        with self._lock:
            if self._finished:
                return
            self._finished = True
        # Known before anyone sees it gone: dropped (the session runs on) or not.
        if self.ended is None and self.dropped is None and not self._closing and self._session_answers():
            self.dropped = "its connection closed without a word"
        with self._lock:
            self._gone.set()
            waiting, self._futures = list(self._futures.values()), {}
        for fut in waiting:
            if not fut.done():
                fut.set_result(CommandResult.refused(f"session {self.info.id} is gone"))
        if self.ended is None and self.dropped is None and not self._closing:
            self._pumps_to_zero()

    def _session_answers(self) -> bool:
        """The session's process is alive and accepts connections on its socket: the
        connection closed, the session did not (one that dies closes its socket)."""
        settled = time.monotonic() + GONE_SETTLE
        while pid_alive(self.info.pid):
            if time.monotonic() >= settled:
                break
            time.sleep(0.01)
        else:
            return False
        probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        probe.settimeout(1.0)
        try:
            with unix_address(self._path) as address:
                probe.connect(address)
        except OSError:
            return False
        finally:
            probe.close()
        return True

    def read_on(self, loop: asyncio.AbstractEventLoop) -> None:
        """Read the session on `loop` (the screen's, from its own thread) instead of
        this client's thread: one thread fewer between the session and the screen;
        futures then complete on that loop's thread."""
        if self._loop is not None or self._gone.is_set() or self._closing:
            return
        os.write(self._wake_w, b"!")
        self._thread.join()
        if self._gone.is_set():
            return
        self._loop = loop
        loop.add_reader(self._sock.fileno(), self._readable)

    def _readable(self) -> None:
        with self._read_lock:
            ok = self._receive()
        if not ok and self._loop is not None:
            self._loop.remove_reader(self._sock.fileno())
            self._loop = None
            # (pumps to 0 over a DAQ link of our own may take a timeout: not on the screen's thread)
            threading.Thread(target=self._finish, name="quadtank-session-gone", daemon=True).start()

    def _read_on_a_thread(self) -> None:
        """Back from an event loop (it may be closed, or still running on another
        thread) to a thread of this client's."""
        loop, self._loop = self._loop, None
        if loop is None:
            return
        fd = self._sock.fileno()
        try:
            if loop.is_running():
                loop.call_soon_threadsafe(loop.remove_reader, fd)
            elif not loop.is_closed():
                loop.remove_reader(fd)
        except (RuntimeError, ValueError, OSError):
            pass  # closed meanwhile: its registrations went with it
        try:
            while os.read(self._wake_r, 512) and select.select([self._wake_r], [], [], 0)[0]:
                pass
        except OSError:
            pass
        self._thread = threading.Thread(target=self._listen, name="quadtank-session-client", daemon=True)
        self._thread.start()

    def _handle(self, message: Any) -> None:
        if isinstance(message, Update):
            if message.cleared:
                self._history.clear()
            if len(message.rows):
                self._history.extend(message.rows)
            snap = message.snapshot
            if snap.params is None:
                snap = replace(snap, params=self._params)
            else:
                self._params = snap.params
            self._snap = snap
        elif isinstance(message, Result):
            with self._lock:
                fut = self._futures.pop(message.id, None)
            if fut is not None and not fut.done():
                fut.set_result(message.result)
        elif isinstance(message, Roster):
            self.controller, self.clients, self.role = message.controller, message.clients, message.role
        elif isinstance(message, Ended):
            self.ended = message.reason
        elif isinstance(message, Dropped):
            self.dropped = message.reason

    def _pumps_to_zero(self) -> None:
        """The session died: an operator of an Active session puts the rig's pumps at 0."""
        if self.role != "operator" or self._snap.operation != "Active" or not self.info.daq:
            return
        try:
            from quadtank_tui.daq.open import open_daq

            backend = open_daq(self.info.daq)
            assert backend is not None
            try:
                backend.safe_state()
            finally:
                backend.close()
            self.rescue = "the pumps were commanded to 0 from this client"
        except Exception as exc:  # noqa: BLE001 - say it; the rig's watchdog is the last line
            self.rescue = f"the pumps could NOT be commanded to 0 ({type(exc).__name__}: {exc})"

    # --- lifetime --------------------------------------------------------------------------------

    def stop_session(self, timeout: float = STOP_TIMEOUT) -> bool:
        """Ask the session to stop (pumps at 0, log kept) and wait for it; False if it
        refused or did not stop in time."""
        try:
            self._send(StopSession())
        except OSError:
            return self._gone.is_set()
        return self._gone.wait(timeout) and self.ended is not None

    def start(self) -> None:
        """The session samples already (EngineHandle users call start())."""

    def stop(self) -> None:
        """Leave the session: detach, or stop it if Exit chose so (`stop_on_close`)."""
        self.close()

    def close(self) -> None:
        """Detach (or stop the session if `stop_on_close`); idempotent."""
        self._read_on_a_thread()
        if self.stop_on_close and not self._gone.is_set():
            self.stop_session()
        self._closing = True
        try:
            self._sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self._thread.join(timeout=2.0)
        try:
            self._sock.close()
        except OSError:
            pass
        for fd in (self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass
        self._wake_r = self._wake_w = -1
        if self._let_go is not None:
            self._let_go()

    def __enter__(self) -> SessionClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def stop_session_at(path: str | Path, timeout: float = STOP_TIMEOUT, *, expect: SessionInfo | None = None) -> str:
    """Ask the session at `path` to stop (pumps at 0, log kept) without attaching;
    returns its reason once it has stopped.  SessionError if it refused (not its
    owner nor an administrator), did not stop within `timeout`, or (`expect`: its
    record) the process on the socket is not the record's (check_peer)."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.settimeout(timeout)
    try:
        connect(sock, path, min(timeout, ATTACH_TIMEOUT))
        check_peer(sock, path, expect)
        sock.sendall(encode(Hello("control", "stop")) + encode(StopSession()))
        reader = LineReader(MAX_SESSION_LINE)
        while True:
            data = sock.recv(1 << 20)
            if not data:
                raise SessionError(f"the session at {path} hung up without saying it stopped")
            for line in reader.feed(data):
                message = decode(line)
                if isinstance(message, Refused):
                    raise SessionError(message.reason)
                if isinstance(message, Ended):
                    return message.reason
    except socket.timeout:
        raise SessionError(f"the session at {path} did not stop within {timeout:g} s") from None
    except (OSError, ProtocolError) as exc:
        if isinstance(exc, SessionError):
            raise
        raise _unreachable(path, exc) from None
    finally:
        sock.close()


def check_peer(sock: socket.socket, path: str | Path, expect: SessionInfo | None) -> None:
    """SessionError unless the process listening on the connected `sock` is the
    session `expect` describes: the kernel's SO_PEERCRED (the pid and uid of the
    process that listens) must be the record's pid and uid.  A socket someone else
    put where a record points, answering "Ended" to a stop, is refused before a
    byte is sent.  `expect` None: not checked (our own child's socket)."""
    if expect is None:
        return
    from quadtank_tui.session.roles import peer_of, user_name

    try:
        peer = peer_of(sock)
    except OSError as exc:
        raise SessionError(f"the session at {path}: whose socket it is cannot be told ({exc.strerror or exc})") \
            from None
    if peer.uid != expect.uid or peer.pid != expect.pid:
        raise SessionError(f"the socket at {path} is not session {expect.id}'s: it is answered by pid {peer.pid} "
                           f"of {user_name(peer.uid)}, the session is pid {expect.pid} of {user_name(expect.uid)}; "
                           "nothing was sent (an administrator may look at it)")


def connect(sock: socket.socket, path: str | Path, timeout: float) -> None:
    """Connect, trying again for up to `timeout` s while the session's backlog is
    full (EAGAIN: a flood of connections it is turning away)."""
    end = time.monotonic() + timeout
    while True:
        try:
            with unix_address(path) as address:
                sock.connect(address)
            return
        except BlockingIOError:
            if time.monotonic() > end:
                raise
            time.sleep(0.01)


def _unreachable(path: str | Path, exc: Exception) -> SessionError:
    """Why a session's socket could not be reached; refused by its mode: whose it is
    and which group may connect, as the user would ask an administrator."""
    if isinstance(exc, PermissionError):
        import grp
        import os

        from quadtank_tui.session.roles import user_name

        try:
            st = os.stat(path)
            group = grp.getgrgid(st.st_gid).gr_name if st.st_mode & 0o060 else None
        except (OSError, KeyError):
            pass
        else:
            who = f"its owner ({user_name(st.st_uid)})" + (f" and members of group {group}" if group else "")
            return SessionError(f"the session at {path} admits {who} only; you are {user_name(os.getuid())} "
                                "(the lab file's share_group says who may watch others' sessions)")
    reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
    return SessionError(f"cannot reach the session at {path}: {reason}")
