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
MAX_BACKLOG bytes queued it is dropped and may attach again.  A client dropped for
what it did is told why as the connection's last line (`Dropped`, after the rest
of a line it was in the middle of receiving; a peer not let in yet is closed
without a word): without it, the client would take the closed connection for the
session's death and put the pumps of a session that runs on at 0.

Anyone on the machine may connect (the session decides who is let in), so what a
peer can make the session hold is bounded: a line before Hello is at most
MAX_HELLO_LINE bytes and must come within HELLO_TIMEOUT; after it MAX_CLIENT_LINE.
What a peer can make the session do is bounded too: a connection's lines are
handled LINES_PER_TURN per event-loop turn (its reading paused until the rest are
done), so a burst of them never holds a sample back, and a connection that sends
more than MAX_LINE_RATE lines a second (beyond a burst of MAX_LINE_BURST) is
dropped, saying so in the session's output.
A long message (the whole ring buffer on attach) goes out in parts, one encoded per
turn (`send_parts`): what else is sent to that client waits behind them.
One user holds at most MAX_PER_USER connections, and RESERVED of the
MAX_CONNECTIONS are kept for the owner and the administrators: another user's
flood never locks them out.  Out of file descriptors (EMFILE), accept backs off
instead of spinning.

The loop first: a user who connects and hangs up in a loop (a million connections
in 30 s) must not hold a sample back.  Accepting is bounded per event-loop turn
(ACCEPTS_PER_TURN, ACCEPT_TURN_TIME: the listener stays readable, the rest wait
for the next turn, after the sample that is due); a user (not an administrator)
connects at most MAX_CONNECT_RATE times a second beyond a burst of
MAX_CONNECT_BURST, and past that is told so and hung up on at once, before the
connection costs a reader, a timer or a line to decode.  What the session turns
away is said in its output once per user a minute (`Refusals`): the first at once,
then how many more there were; one line each filled a root session's output with
1,889 lines in 30 s.

The connecting user is whom the kernel says (SO_PEERCRED), never what a message
claims.
"""

from __future__ import annotations

import asyncio
import collections
import errno
import os
import socket
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Literal

from quadtank_tui.session.unixpath import unix_address
from quadtank_tui.session.protocol import (
    CLIENT_MESSAGES, MAX_CLIENT_LINE, MAX_HELLO_LINE, Dropped, LineReader, ProtocolError, Refused, decode, encode,
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
#: Lines of one connection handled per event-loop turn: a refused Submit costs
#: about 50 us, an operator's SetParams of a whole .par about a millisecond.
LINES_PER_TURN = 8
#: Lines a second a connection may send on average, and in one burst, before it is
#: dropped: a screen sends a few per key press (key repeat: 30 a second), a burst of
#: pasted or scripted commands a few hundred; 10000 refused Submits in 5 s (the
#: review's flood) stalled the sampling for a second.
MAX_LINE_RATE = 200.0
MAX_LINE_BURST = 1000
#: Seconds spent encoding a long message's parts per event-loop turn (send_parts):
#: a part of the history takes about 0.12 ms, so a few go per turn.
PARTS_PER_TURN_TIME = 0.001
#: Connections accepted per event-loop turn, and the wall time one turn's accepts may
#: take, s: a sample due waits behind one turn at most (the driver gives the loop
#: its turns until FINE_WAIT before the deadline), and a connection accepted, looked
#: up (SO_PEERCRED, the user's name) and let in costs 30-60 us.
ACCEPTS_PER_TURN = 8
ACCEPT_TURN_TIME = 0.0003
#: Seconds the listener rests after a turn that left connections in the backlog: a
#: churn then takes at most about ACCEPT_TURN_TIME / ACCEPT_REST of the loop's
#: thread.  Unpaced, the turns followed each other at once and the thread, at
#: real-time priority on a rig, used its whole core: the kernel's real-time
#: throttling then held it back 50 ms in every second, and samples came 5-12 ms late.
ACCEPT_REST = 0.002
#: Connections a second one user (not an administrator) may open on average, and in
#: one burst: a screen attaches once, `quadtank sessions` and `stop` connect once a
#: session; beyond it each is told Refused and closed at once.
MAX_CONNECT_RATE = 20.0
MAX_CONNECT_BURST = 50.0
#: Seconds between two lines in the output about what one user had turned away.
REFUSALS_EVERY = 60.0
#: Seconds a dropped client's last words (Dropped) may take to go out before its
#: socket is closed anyway (a client that does not read them gets none).
FAREWELL_TIMEOUT = 2.0

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
    lines: collections.deque[bytes] = field(default_factory=collections.deque)  # read, not yet handled
    reading: bool = True           # the loop watches it for lines (paused while `lines` are left)
    allowance: float = field(default_factory=lambda: float(MAX_LINE_BURST))  # lines it may send now
    counted: float = field(default_factory=time.monotonic)  # when `allowance` was refilled
    parts: Iterator[bytes] | None = None  # a long message still being encoded (send_parts)
    held: bytearray = field(default_factory=bytearray)  # what is sent meanwhile, behind it

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
        self._farewells: dict[socket.socket, _Farewell] = {}
        #: Connections with lines queued that the socket has not taken yet, and with a
        #: long message still being encoded (send_parts).
        self.writing = 0
        self.producing = 0
        #: Connections turned away (limits, a silent peer, a bad line) and accept's pauses, for the record.
        self.refused = 0
        self.paused = 0
        self.accepted = 0
        self.rests = 0
        #: Per user id: connections it may still open now, and when that was counted.
        self._connect_allowance: dict[int, tuple[float, float]] = {}
        self.refusals = Refusals(_note, aloop)
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
        """At most ACCEPTS_PER_TURN connections, for at most ACCEPT_TURN_TIME: the
        rest stay in the backlog for the next turn (the listener is still readable)."""
        end = time.monotonic() + ACCEPT_TURN_TIME
        for _ in range(ACCEPTS_PER_TURN):
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
            self.accepted += 1
            self._take(sock)
            if time.monotonic() > end:
                break
        # The turn's share is used up and more may wait: rest a moment (see ACCEPT_REST).
        self.rests += 1
        self._unlisten()
        self.aloop.call_later(ACCEPT_REST, self._resume_accept)

    def _take(self, sock: socket.socket) -> None:
        """A connection just accepted: let in, or told why not and closed."""
        sock.setblocking(False)
        try:
            peer = self._peer_of(sock)
        except OSError:
            sock.close()
            return
        rank = self._rank(peer)
        why = self._too_often(peer, rank) or self._no_room(peer, rank)
        if why is not None:
            self.refused += 1
            self.refusals.note(peer, why)
            try:
                sock.send(encode(Refused(why)))  # a fresh socket takes one short line
            except OSError:
                pass
            sock.close()
            return
        conn = Connection(sock, peer, rank)
        self.connections.append(conn)
        self._per_user[peer.uid] = self._per_user.get(peer.uid, 0) + 1
        self.aloop.add_reader(sock.fileno(), self._read, conn)
        conn.silence = self.aloop.call_later(HELLO_TIMEOUT, self._silent, conn)

    def _too_often(self, peer: Peer, rank: Rank) -> str | None:
        """Count one more connection of `peer`'s user; why it is one too many (None: not)."""
        if rank == "admin":
            return None
        now = time.monotonic()
        left, counted = self._connect_allowance.get(peer.uid, (MAX_CONNECT_BURST, now))
        left = min(MAX_CONNECT_BURST, left + (now - counted) * MAX_CONNECT_RATE)
        if left < 1.0:
            self._connect_allowance[peer.uid] = (left, now)
            return (f"{peer.user} connects to this session more than {MAX_CONNECT_RATE:g} times a second "
                    f"(beyond a burst of {MAX_CONNECT_BURST:g}); try again in a moment")
        self._connect_allowance[peer.uid] = (left - 1.0, now)
        if len(self._connect_allowance) > 4 * MAX_CONNECTIONS:  # users long gone: their allowance is full again
            full = [uid for uid, (n, t) in self._connect_allowance.items()
                    if n + (now - t) * MAX_CONNECT_RATE >= MAX_CONNECT_BURST]
            for uid in full:
                del self._connect_allowance[uid]
        return None

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
            lines = conn.reader.feed(data)
        except ProtocolError as exc:
            self.refused += 1
            self.drop(conn, f"it sent {exc}")
            return
        if lines and self._flooding(conn, len(lines)):
            return
        conn.lines.extend(lines)
        self._handle(conn)

    def _flooding(self, conn: Connection, n: int) -> bool:
        """Count `n` more lines from `conn`; past its allowance it is dropped (True)."""
        now = time.monotonic()
        conn.allowance = min(MAX_LINE_BURST, conn.allowance + (now - conn.counted) * MAX_LINE_RATE) - n
        conn.counted = now
        if conn.allowance >= 0:
            return False
        self.refused += 1
        self.drop(conn, f"it sent lines faster than {MAX_LINE_RATE:g} a second (beyond a burst of {MAX_LINE_BURST})")
        return True

    def _handle(self, conn: Connection) -> None:
        """Up to LINES_PER_TURN of the lines read from `conn`; the rest next turn,
        its reading paused meanwhile (what it holds stays one read's worth)."""
        for _ in range(LINES_PER_TURN):
            if not conn.lines:
                break
            if conn not in self.connections or conn.closing:
                conn.lines.clear()
                return
            line = conn.lines.popleft()
            try:
                self._on_message(conn, decode(line, CLIENT_MESSAGES))
                if conn.role is not None:
                    conn.reader.limit = MAX_CLIENT_LINE  # let in: commands may be longer than a Hello
            except ProtocolError as exc:
                self.refused += 1
                self.drop(conn, f"it sent a line that is not a message of the session's protocol ({exc})")
                return
            except Exception as exc:  # noqa: BLE001 - what one client's message broke ends that client only
                self.drop(conn, f"its message failed: {type(exc).__name__}: {exc}")
                return
        if conn not in self.connections:
            return
        if conn.lines:
            if conn.reading:
                self.aloop.remove_reader(conn.sock.fileno())
                conn.reading = False
            self.aloop.call_soon(self._handle, conn)
        elif not conn.reading:
            self.aloop.add_reader(conn.sock.fileno(), self._read, conn)
            conn.reading = True

    def send(self, conn: Connection, payload: bytes, *, close: bool = False) -> None:
        """Queue `payload` (encoded lines) for `conn`; `close`: then hang up."""
        if conn not in self.connections or conn.closing:
            return
        if not self._queue(conn, payload, conn.held if conn.parts is not None else conn.out):
            return
        conn.closing = close
        self._write(conn)

    def send_parts(self, conn: Connection, parts: Iterator[bytes]) -> None:
        """Queue the lines `parts` yields for `conn`, as many per event-loop turn as
        PARTS_PER_TURN_TIME allows (each is encoded when its turn comes: a long
        message never holds a sample back); what is sent to `conn` meanwhile follows them."""
        if conn not in self.connections or conn.closing or conn.parts is not None:
            return
        conn.parts = parts
        self.producing += 1
        self.aloop.call_soon(self._next_part, conn)

    def _next_part(self, conn: Connection) -> None:
        end = time.monotonic() + PARTS_PER_TURN_TIME
        while conn in self.connections and conn.parts is not None:
            try:
                part = next(conn.parts, None)
            except Exception as exc:  # noqa: BLE001 - what fails for one client ends that client only
                self.drop(conn, f"a message to it failed: {type(exc).__name__}: {exc}")
                return
            if part is None:  # all sent: what waited behind them goes next
                self._parts_done(conn)
                conn.out += conn.held
                conn.held = bytearray()
            elif not self._queue(conn, part, conn.out):
                return
            elif time.monotonic() > end:
                self.aloop.call_soon(self._next_part, conn)
                break
        if conn in self.connections:
            self._write(conn)

    def _parts_done(self, conn: Connection) -> None:
        if conn.parts is not None:
            conn.parts = None
            self.producing -= 1

    def _queue(self, conn: Connection, payload: bytes, into: bytearray) -> bool:
        """Append `payload` to `into` (`conn`'s out or held); False: the backlog is
        full and `conn` was dropped."""
        if len(conn.out) + len(conn.held) + len(payload) > MAX_BACKLOG or \
                conn.rank == "other" and self._others_queued + len(payload) > MAX_BACKLOG_OTHERS:
            self.drop(conn, "it fell too far behind in reading the session's updates")
            return False
        into += payload
        if conn.rank == "other":
            self._others_queued += len(payload)
        return True

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
        if conn.closing and conn.parts is None:
            self.drop(conn)

    def drop(self, conn: Connection, why: str | None = None) -> None:
        """Close `conn`; `why`: it is dropped for what it did, noted in the session's
        output and, once let in, told so (Dropped) after the rest of the line it was
        receiving."""
        if conn not in self.connections:
            return
        if why is not None:
            self.refusals.note(conn.peer, why, dropped=True)
        farewell = b""
        if why is not None and conn.role is not None:  # before its Hello it is no client of ours yet
            rest = bytes(conn.out[:conn.out.find(b"\n") + 1])  # a line half sent is finished first
            farewell = rest + encode(Dropped(why))
        self.connections.remove(conn)
        if conn.rank == "other":
            self._others_queued -= len(conn.out) + len(conn.held)
        self._parts_done(conn)
        conn.lines.clear()
        left = self._per_user.get(conn.peer.uid, 1) - 1
        if left > 0:
            self._per_user[conn.peer.uid] = left
        else:
            self._per_user.pop(conn.peer.uid, None)
        fd = conn.sock.fileno()
        if conn.reading:
            self.aloop.remove_reader(fd)
            conn.reading = False
        if conn.writing:
            self.aloop.remove_writer(fd)
            conn.writing = False
            self.writing -= 1
        if conn.silence is not None:
            conn.silence.cancel()
        if farewell and not self._closed:
            _Farewell(self, conn.sock, farewell)
        else:
            conn.sock.close()
        self._on_gone(conn)

    async def flush_all(self, timeout: float) -> None:
        """At the end: no one new; let the queued lines go out for up to `timeout` s."""
        self._unlisten()
        end = time.monotonic() + timeout
        while any(c.out or c.parts is not None for c in self.connections) and time.monotonic() < end:
            await asyncio.sleep(0.01)

    def close(self) -> None:
        self._unlisten()
        self._closed = True
        self.refusals.flush()
        for farewell in list(self._farewells.values()):
            farewell.done()
        for conn in list(self.connections):
            conn.closing = True
            self.drop(conn)
        self.listener.close()


class Refusals:
    """What the session turned away, in its output once per user a minute: the first
    refusal of a user at once (who, which process, why), then, REFUSALS_EVERY after
    it, how many more there were and the last reason (a count by reason would be
    one more thing a user could make grow)."""

    def __init__(self, note: Callable[[str], None], aloop: asyncio.AbstractEventLoop) -> None:
        self._note = note
        self._aloop = aloop
        #: uid -> [user name, refusals since the last line, last reason, the timer of the next line]
        self._quiet: dict[int, list[Any]] = {}

    def note(self, peer: Peer, why: str, *, dropped: bool = False) -> None:
        what = f"dropped {peer.user} (pid {peer.pid}): {why}" if dropped else \
            f"turned away {peer.user} (pid {peer.pid}): {why}"
        entry = self._quiet.get(peer.uid)
        if entry is not None:
            entry[1] += 1
            entry[2] = what
            return
        self._note(what)
        timer = self._aloop.call_later(REFUSALS_EVERY, self._summary, peer.uid)
        self._quiet[peer.uid] = [peer.user, 0, what, timer]

    def _summary(self, uid: int) -> None:
        entry = self._quiet.pop(uid, None)
        if entry is not None and entry[1]:
            self._say(entry)

    def _say(self, entry: list[Any]) -> None:
        user, n, last = entry[0], entry[1], entry[2]
        self._note(f"{user}: {n} more connection{'s' if n != 1 else ''} turned away or dropped in the last "
                   f"{REFUSALS_EVERY:g} s (the last: {last})")

    def flush(self) -> None:
        """The counts not said yet (the session ends)."""
        for uid in list(self._quiet):
            entry = self._quiet.pop(uid)
            entry[3].cancel()
            if entry[1]:
                self._say(entry)


class _Farewell:
    """A dropped connection's last words, written as its socket takes them, for at
    most FAREWELL_TIMEOUT; then the socket is closed.  The connection is gone for
    the session already (roster, limits, on_gone): only these bytes are left."""

    def __init__(self, server: Server, sock: socket.socket, data: bytes) -> None:
        self._server = server
        self._sock = sock
        self._fd = sock.fileno()
        self._rest = bytearray(data)
        self._watching = False
        self._timer = server.aloop.call_later(FAREWELL_TIMEOUT, self.done)
        server._farewells[sock] = self
        self._write()
        if sock in server._farewells:
            server.aloop.add_writer(self._fd, self._write)
            self._watching = True

    def _write(self) -> None:
        try:
            n = self._sock.send(self._rest)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            n = len(self._rest)  # the peer is gone: nobody left to tell
        del self._rest[:n]
        if not self._rest:
            self.done()

    def done(self) -> None:
        if self._server._farewells.pop(self._sock, None) is None:
            return
        self._timer.cancel()
        if self._watching:
            self._server.aloop.remove_writer(self._fd)
        self._sock.close()


def listen(path: str, *, anyone: bool = False) -> socket.socket:
    """A Unix socket at `path` only its owner may connect to (bound under a umask
    that allows nobody else, so no one can connect before the mode is right); with
    `anyone`, every local user may connect, and the session decides (SO_PEERCRED):
    who may - its owner, the lab's administrators, its share group - is more than
    a file mode can say (one group, and only a group its owner is in)."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    old = os.umask(0o177)
    try:
        with unix_address(path) as address:  # a path longer than sun_path: through its folder
            sock.bind(address)
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
