"""The session's socket: connections that never make the loop wait.

Every connection is non-blocking.  What a client sends is split into lines and
decoded (a line that is not a message drops the client); what the session sends is
queued per connection and written when the socket takes it, so a slow or stopped
client (a TUI suspended with Ctrl-Z, a link that stalls) costs the sampling nothing:
past MAX_BACKLOG bytes queued it is dropped and may attach again.

The connecting user is whom the kernel says (SO_PEERCRED), never what a message
claims.
"""

from __future__ import annotations

import os
import selectors
import socket
from dataclasses import dataclass, field
from typing import Any, Callable

from quadtank_tui.session.protocol import CLIENT_MESSAGES, MAX_CLIENT_LINE, LineReader, ProtocolError, decode
from quadtank_tui.session.roles import Peer, peer_of as kernel_peer

#: Bytes queued for one client before it is dropped as too slow.
MAX_BACKLOG = 64 << 20


@dataclass(eq=False)
class Connection:
    sock: socket.socket
    peer: Peer
    reader: LineReader = field(default_factory=lambda: LineReader(MAX_CLIENT_LINE))
    out: bytearray = field(default_factory=bytearray)
    role: str | None = None        # None until its Hello was accepted
    since: float = 0.0             # wall time (time.time) it attached
    closing: bool = False          # close once `out` is written

    @property
    def name(self) -> str:
        return f"{self.peer.user} (pid {self.peer.pid})"


class Server:
    """The listening socket and the connections, on the host's selector.

    on_message(conn, message) : a decoded client message
    on_gone(conn) : a connection closed (after its Hello or not)
    """

    def __init__(self, listener: socket.socket, selector: selectors.BaseSelector,
                 on_message: Callable[[Connection, Any], None], on_gone: Callable[[Connection], None], *,
                 peer_of: Callable[[socket.socket], Peer] = kernel_peer) -> None:
        self.listener = listener
        self.selector = selector
        self.connections: list[Connection] = []
        self._on_message = on_message
        self._on_gone = on_gone
        self._peer_of = peer_of
        listener.setblocking(False)
        selector.register(listener, selectors.EVENT_READ, self._accept)

    def _accept(self, mask: int) -> None:
        while True:
            try:
                sock, _ = self.listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return
            sock.setblocking(False)
            try:
                peer = self._peer_of(sock)
            except OSError:
                sock.close()
                continue
            conn = Connection(sock, peer)
            self.connections.append(conn)
            self.selector.register(sock, selectors.EVENT_READ, lambda m, c=conn: self._ready(c, m))

    def _ready(self, conn: Connection, mask: int) -> None:
        if mask & selectors.EVENT_WRITE:
            self._write(conn)
        if mask & selectors.EVENT_READ and conn in self.connections:
            self._read(conn)

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
        except ProtocolError:
            self.drop(conn)

    def send(self, conn: Connection, payload: bytes, *, close: bool = False) -> None:
        """Queue `payload` (encoded lines) for `conn`; `close`: then hang up."""
        if conn not in self.connections or conn.closing:
            return
        if len(conn.out) + len(payload) > MAX_BACKLOG:
            self.drop(conn)
            return
        conn.out += payload
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
        if conn.out:
            self.selector.modify(conn.sock, selectors.EVENT_READ | selectors.EVENT_WRITE,
                                 lambda m, c=conn: self._ready(c, m))
        else:
            if conn.closing:
                self.drop(conn)
                return
            self.selector.modify(conn.sock, selectors.EVENT_READ, lambda m, c=conn: self._ready(c, m))

    def drop(self, conn: Connection) -> None:
        if conn not in self.connections:
            return
        self.connections.remove(conn)
        try:
            self.selector.unregister(conn.sock)
        except (KeyError, ValueError):
            pass
        conn.sock.close()
        self._on_gone(conn)

    def flush_all(self, timeout: float) -> None:
        """At the end: let the queued lines go out for up to `timeout` s."""
        import time

        end = time.monotonic() + timeout
        while any(c.out for c in self.connections) and time.monotonic() < end:
            for key, mask in self.selector.select(max(0.0, end - time.monotonic())):
                if key.fileobj is not self.listener:
                    key.data(mask)

    def close(self) -> None:
        for conn in list(self.connections):
            conn.closing = True
            self.drop(conn)
        try:
            self.selector.unregister(self.listener)
        except (KeyError, ValueError):
            pass
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
    sock.listen(16)
    return sock
