"""The session's socket: connections that never make the loop wait, and that no
other user can use to end the session or crowd its owner out.

The server lives on the session driver's asyncio event loop: the listener and
each connection are non-blocking sockets watched by the loop (`add_reader`,
`add_writer`), and the timers (a silent peer, accept's pause) are the loop's.
Not asyncio's own Unix server and transports: their accept retries after running
out of descriptors at a fixed second with a traceback in the output, and their
write buffers grow without the per-user accounting below.

Every connection is non-blocking.  What a client sends is split into lines and
decoded (a line that is not a message drops that client, never the session: the
same for anything its message makes go wrong); what the session sends is queued
per connection and written when the socket takes it, so a slow or stopped client
(a TUI suspended with Ctrl-Z, a link that stalls) costs the sampling nothing: past
MAX_BACKLOG bytes queued it is dropped and may attach again.

Anyone on the machine may connect (the session decides who is let in), so what a
peer can make the session hold is bounded: a line before Hello is at most
MAX_HELLO_LINE bytes and must come within HELLO_TIMEOUT; after it MAX_CLIENT_LINE.
One user holds at most MAX_PER_USER connections, and RESERVED of the
MAX_CONNECTIONS are kept for the owner and the administrators: another user's
flood never locks them out.  Out of file descriptors (EMFILE), accept backs off
instead of spinning.

The connecting user is whom the kernel says (SO_PEERCRED), never what a message
claims.
"""

from __future__ import annotations

import asyncio
import errno
import os
import socket
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Literal

from quadtank_tui.session.protocol import (
    CLIENT_MESSAGES, MAX_CLIENT_LINE, MAX_HELLO_LINE, LineReader, ProtocolError, Refused, decode, encode,
)
from quadtank_tui.session.roles import Peer, peer_of as kernel_peer

#: Bytes queued for one client before it is dropped as too slow, and for all the
#: clients that are neither the owner nor an administrator together (16 observers
#: of one user each 64 MB behind would be a gigabyte of the session's memory).
MAX_BACKLOG = 64 << 20
MAX_BACKLOG_OTHERS = 256 << 20
#: Connections a session holds at once, of which RESERVED only for its owner and
#: the administrators; one user (not an administrator) holds at most MAX_PER_USER.
MAX_CONNECTIONS = 128
RESERVED = 32
MAX_PER_USER = 16
#: Seconds a new connection has to say Hello (a client says it at once).
HELLO_TIMEOUT = 10.0
#: Seconds accept pauses after running out of descriptors or memory, doubling up to the second.
ACCEPT_BACKOFF = (0.05, 1.0)

#: Who a peer is to this session: an administrator, its owner, anyone else.
Rank = Literal["admin", "owner", "other"]


@dataclass(eq=False)
class Connection:
    sock: socket.socket
    peer: Peer
    rank: Rank = "other"
    reader: LineReader = field(default_factory=lambda: LineReader(MAX_HELLO_LINE))
    out: bytearray = field(default_factory=bytearray)
    role: str | None = None        # None until its Hello was accepted
    since: float = 0.0             # wall time (time.time) it attached
    opened: float = field(default_factory=time.monotonic)
    closing: bool = False          # close once `out` is written
    writing: bool = False          # the loop watches it for room to write `out`
    silence: asyncio.TimerHandle | None = None  # drops it if it has not said Hello by then

    @property
    def name(self) -> str:
        return f"{self.peer.user} (pid {self.peer.pid})"


class Server:
    """The listening socket and the connections, on the driver's event loop.

    on_message(conn, message) : a decoded client message
    on_gone(conn) : a connection closed (after its Hello or not)
    rank(peer) : an administrator, the owner, or anyone else (who may use the reserve)
    """

    def __init__(self, listener: socket.socket, aloop: asyncio.AbstractEventLoop,
                 on_message: Callable[[Connection, Any], None], on_gone: Callable[[Connection], None], *,
                 peer_of: Callable[[socket.socket], Peer] = kernel_peer,
                 rank: Callable[[Peer], Rank] = lambda peer: "other") -> None:
        self.listener = listener
        self.aloop = aloop
        self.connections: list[Connection] = []
        self._on_message = on_message
        self._on_gone = on_gone
        self._peer_of = peer_of
        self._rank = rank
        self._per_user: dict[int, int] = {}
        self._others_queued = 0   # bytes in the `out` of connections of rank "other"
        self._backoff = 0.0
        self._listening = False
        self._closed = False
        #: Connections with lines queued that the socket has not taken yet.
        self.writing = 0
        #: Connections turned away (limits, a silent peer, a bad line) and accept's pauses, for the record.
        self.refused = 0
        self.paused = 0
        listener.setblocking(False)
        self._listen()

    def _listen(self) -> None:
        if not self._listening and not self._closed:
            self.aloop.add_reader(self.listener.fileno(), self._accept)
            self._listening = True

    def _unlisten(self) -> None:
        if self._listening:
            self.aloop.remove_reader(self.listener.fileno())
            self._listening = False

    def _accept(self) -> None:
        while True:
            try:
                sock, _ = self.listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            except ConnectionAbortedError:
                continue
            except OSError as exc:  # EMFILE, ENFILE, ENOBUFS, ENOMEM: the listener stays readable
                self._pause_accept(exc)
                return
            self._backoff = 0.0
            sock.setblocking(False)
            try:
                peer = self._peer_of(sock)
            except OSError:
                sock.close()
                continue
            rank = self._rank(peer)
            why = self._no_room(peer, rank)
            if why is not None:
                self.refused += 1
                try:
                    sock.send(encode(Refused(why)))  # a fresh socket takes one short line
                except OSError:
                    pass
                sock.close()
                continue
            conn = Connection(sock, peer, rank)
            self.connections.append(conn)
            self._per_user[peer.uid] = self._per_user.get(peer.uid, 0) + 1
            self.aloop.add_reader(sock.fileno(), self._read, conn)
            conn.silence = self.aloop.call_later(HELLO_TIMEOUT, self._silent, conn)

    def _no_room(self, peer: Peer, rank: Rank) -> str | None:
        """Why `peer` is turned away now (None: let in)."""
        total = len(self.connections)
        mine = self._per_user.get(peer.uid, 0)
        if rank != "admin" and mine >= MAX_PER_USER:
            return f"{peer.user} has {mine} connections to this session already (at most {MAX_PER_USER})"
        room = MAX_CONNECTIONS if rank != "other" else MAX_CONNECTIONS - RESERVED
        if total >= room:
            return (f"this session has {total} connections (at most {room}"
                    + (f"; the last {RESERVED} are kept for its owner and the administrators)" if rank == "other"
                       else ")"))
        return None

    def _pause_accept(self, exc: OSError) -> None:
        """Out of descriptors or memory: stop listening for a while (a readable
        listener whose accept fails would wake the loop at once, forever)."""
        self._backoff = min(ACCEPT_BACKOFF[1], max(ACCEPT_BACKOFF[0], 2 * self._backoff))
        self.paused += 1
        self._unlisten()
        self.aloop.call_later(self._backoff, self._resume_accept)
        if self.paused == 1 or exc.errno not in (errno.EMFILE, errno.ENFILE):
            _note(f"accept paused {self._backoff:g} s: {exc}")

    def _resume_accept(self) -> None:
        if not self._closed:
            self._listen()
            self._accept()

    def _silent(self, conn: Connection) -> None:
        """HELLO_TIMEOUT after it connected: a peer that has not said Hello goes."""
        if conn.role is None and conn in self.connections:
            self.refused += 1
            self.drop(conn)

    def _read(self, conn: Connection) -> None:
        try:
            data = conn.sock.recv(1 << 16)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            self.drop(conn)
            return
        try:
            for line in conn.reader.feed(data):
                if conn not in self.connections or conn.closing:
                    return
                self._on_message(conn, decode(line, CLIENT_MESSAGES))
                if conn.role is not None:
                    conn.reader.limit = MAX_CLIENT_LINE  # let in: commands may be longer than a Hello
        except ProtocolError:
            self.refused += 1
            self.drop(conn)
        except Exception as exc:  # noqa: BLE001 - what one client's message broke ends that client only
            _note(f"dropped {conn.name}: its message failed: {type(exc).__name__}: {exc}")
            self.drop(conn)

    def send(self, conn: Connection, payload: bytes, *, close: bool = False) -> None:
        """Queue `payload` (encoded lines) for `conn`; `close`: then hang up."""
        if conn not in self.connections or conn.closing:
            return
        if len(conn.out) + len(payload) > MAX_BACKLOG or \
                conn.rank == "other" and self._others_queued + len(payload) > MAX_BACKLOG_OTHERS:
            self.drop(conn)
            return
        conn.out += payload
        if conn.rank == "other":
            self._others_queued += len(payload)
        conn.closing = close
        self._write(conn)

    def broadcast(self, payload: bytes) -> None:
        for conn in list(self.connections):
            if conn.role is not None:
                self.send(conn, payload)

    def _write(self, conn: Connection) -> None:
        while conn.out:
            try:
                n = conn.sock.send(conn.out)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                self.drop(conn)
                return
            del conn.out[:n]
            if conn.rank == "other":
                self._others_queued -= n
        if conn.out:
            if not conn.writing:
                self.aloop.add_writer(conn.sock.fileno(), self._write, conn)
                conn.writing = True
                self.writing += 1
            return
        if conn.writing:
            self.aloop.remove_writer(conn.sock.fileno())
            conn.writing = False
            self.writing -= 1
        if conn.closing:
            self.drop(conn)

    def drop(self, conn: Connection) -> None:
        if conn not in self.connections:
            return
        self.connections.remove(conn)
        if conn.rank == "other":
            self._others_queued -= len(conn.out)
        left = self._per_user.get(conn.peer.uid, 1) - 1
        if left > 0:
            self._per_user[conn.peer.uid] = left
        else:
            self._per_user.pop(conn.peer.uid, None)
        fd = conn.sock.fileno()
        self.aloop.remove_reader(fd)
        if conn.writing:
            self.aloop.remove_writer(fd)
            conn.writing = False
            self.writing -= 1
        if conn.silence is not None:
            conn.silence.cancel()
        conn.sock.close()
        self._on_gone(conn)

    async def flush_all(self, timeout: float) -> None:
        """At the end: no one new; let the queued lines go out for up to `timeout` s."""
        self._unlisten()
        end = time.monotonic() + timeout
        while any(c.out for c in self.connections) and time.monotonic() < end:
            await asyncio.sleep(0.01)

    def close(self) -> None:
        self._unlisten()
        self._closed = True
        for conn in list(self.connections):
            conn.closing = True
            self.drop(conn)
        self.listener.close()


def listen(path: str, *, anyone: bool = False) -> socket.socket:
    """A Unix socket at `path` only its owner may connect to (bound under a umask
    that allows nobody else, so no one can connect before the mode is right); with
    `anyone`, every local user may connect, and the session decides (SO_PEERCRED):
    who may - its owner, the lab's administrators, its share group - is more than
    a file mode can say (one group, and only a group its owner is in)."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    old = os.umask(0o177)
    try:
        sock.bind(path)
    finally:
        os.umask(old)
    if anyone:
        os.chmod(path, 0o666)
    sock.listen(64)
    return sock


def _note(line: str) -> None:
    """One line in the session's output file (its stderr)."""
    try:
        print(f"{time.strftime('%Y-%m-%d %H:%M:%S')} {line}", file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass
