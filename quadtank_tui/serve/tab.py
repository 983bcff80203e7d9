"""One browser tab's program: `quadtank` run as the tab's user, spoken to in
textual-serve's protocol.

The tab's process is Textual's web driver: it prints `__GANGLION__`, then packets
on stdout (`D` screen bytes, `M` a JSON meta message, `P` a packed one: a file
download, which the server does not relay); it reads packets on stdin (`D` key
bytes, `M` resize/focus/blur/quit).  Each packet is a type byte, a 4-byte
big-endian length and the payload.  The browser's side of the websocket is
textual-serve's textual.js: ["stdin", text], ["resize", {width, height}],
["ping", x] answered ["pong", x], ["focus"], ["blur"].

Ending a tab detaches, never stops: the tab's program is asked to quit (Textual
exits as from a closed terminal; the session runs on), then its stdin closes (the
client's terminal watch sees the hang-up), then SIGTERM, then SIGKILL, each after a
grace.  Only the tab's own pid is signalled: the session it started is in a
process group of its own and is never touched.
"""

from __future__ import annotations

import asyncio
import json
import os
import signal
import sys
from dataclasses import dataclass
from typing import Awaitable, Callable

#: Most screen bytes one packet from the tab may announce (a full 4K screen's frame
#: is well under 1 MiB); more is a broken program, and the tab ends.
MAX_PACKET = 8 << 20
#: Seconds a tab has to print its prelude (loading the TUI on a busy machine).
START_TIMEOUT = 60.0
#: Seconds between asking a tab to quit and closing its stdin, then SIGTERM, then SIGKILL.
QUIT_GRACE = 3.0
TERM_GRACE = 3.0


@dataclass(frozen=True)
class TabUser:
    """Who a tab runs as: the account's uid, gid, groups and home."""

    name: str
    uid: int
    gid: int
    groups: tuple[int, ...]
    home: str
    shell_path: str = "/usr/local/bin:/usr/bin:/bin"


def encode_packet(kind: bytes, payload: bytes) -> bytes:
    """A packet of the web driver's stdin stream.

    >>> encode_packet(b"D", b"q")
    b'D\\x00\\x00\\x00\\x01q'
    """
    return kind + len(payload).to_bytes(4, "big") + payload


#: The tab's interpreter starts as root with the user's HOME: isolated (-I: no
#: user site-packages, so no ~/.local/.../usercustomize.py or .pth of the user's
#: runs as root; no PYTHON* variables; not the current folder on sys.path).
PYTHON_FLAGS = ("-I",)


def tab_environment(user: TabUser, width: int, height: int, passed: dict[str, str]) -> dict[str, str]:
    """The tab's whole environment: the user's own names, the web driver's settings
    and what the lab passes on (`passed`: QUADTANK_LAB, QUADTANK_RUNTIME of the
    server); nothing else of the server's."""
    env = {
        "HOME": user.home, "USER": user.name, "LOGNAME": user.name, "PATH": user.shell_path,
        "LANG": "C.UTF-8", "TERM": "xterm-256color",
        "TEXTUAL_DRIVER": "textual.drivers.web_driver:WebDriver", "TEXTUAL_FPS": "30",
        "TEXTUAL_COLOR_SYSTEM": "truecolor", "TERM_PROGRAM": "textual",
        "COLUMNS": str(width), "ROWS": str(height), "PYTHONDONTWRITEBYTECODE": "1",
    }
    env.update(passed)
    return env


class Tab:
    """The process behind one websocket.  `to_browser(bytes)` gets screen bytes;
    `on_exit()` is called once when the program has ended (by itself or asked)."""

    def __init__(self, user: TabUser, args: list[str], *, width: int, height: int,
                 to_browser: Callable[[bytes], Awaitable[None]], passed_env: dict[str, str],
                 python: str = sys.executable) -> None:
        self.user, self.args = user, args
        self.width, self.height = width, height
        self._to_browser = to_browser
        self._env = tab_environment(user, width, height, passed_env)
        self._python = python
        self.process: asyncio.subprocess.Process | None = None
        self.started = asyncio.Event()
        self.stderr_tail = b""
        self._reader: asyncio.Task[None] | None = None

    async def start(self) -> None:
        u = self.user
        groups = ",".join(str(g) for g in u.groups)
        self.process = await asyncio.create_subprocess_exec(
            self._python, *PYTHON_FLAGS, "-m", "quadtank_tui.serve.drop", str(u.uid), str(u.gid), groups, u.home, "--",
            *self.args, stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE, env=self._env, cwd="/", start_new_session=True,
            close_fds=True)
        self._reader = asyncio.create_task(self._read())

    async def _read(self) -> None:
        proc = self.process
        assert proc is not None and proc.stdout is not None and proc.stderr is not None
        stderr_task = asyncio.create_task(self._read_stderr(proc.stderr))
        out = proc.stdout
        try:
            line = await asyncio.wait_for(out.readline(), START_TIMEOUT)
            while line and line != b"__GANGLION__\n":  # anything printed before the driver starts
                self.stderr_tail = (self.stderr_tail + line)[-4096:]
                line = await asyncio.wait_for(out.readline(), START_TIMEOUT)
            if not line:
                return
            self.started.set()
            while True:
                head = await out.readexactly(5)
                size = int.from_bytes(head[1:], "big")
                if size > MAX_PACKET:
                    return
                payload = await out.readexactly(size)
                if head[:1] == b"D":
                    await self._to_browser(payload)
                elif head[:1] == b"M":
                    try:
                        meta = json.loads(payload)
                    except ValueError:
                        return
                    if isinstance(meta, dict) and meta.get("type") == "exit":
                        return
        except (asyncio.IncompleteReadError, asyncio.TimeoutError, ConnectionError):
            return
        finally:
            stderr_task.cancel()

    async def _read_stderr(self, err: asyncio.StreamReader) -> None:
        while chunk := await err.read(4096):
            self.stderr_tail = (self.stderr_tail + chunk)[-4096:]

    async def wait_reader(self) -> None:
        """Until the program's output ends (it exited, or closed its screen)."""
        if self._reader is not None:
            await self._reader

    async def _send(self, packet: bytes) -> None:
        proc = self.process
        if proc is None or proc.stdin is None or proc.returncode is not None:
            return
        try:
            proc.stdin.write(packet)
            await proc.stdin.drain()
        except (ConnectionError, RuntimeError):
            pass

    async def keys(self, text: str) -> None:
        await self._send(encode_packet(b"D", text.encode("utf-8")))

    async def meta(self, message: dict[str, object]) -> None:
        await self._send(encode_packet(b"M", json.dumps(message).encode("utf-8")))

    async def resize(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        await self.meta({"type": "resize", "width": width, "height": height})

    async def close(self) -> int | None:
        """Detach: ask the program to quit, then close its stdin, then SIGTERM, then
        SIGKILL (each after its grace); the exit status (None: never started)."""
        proc = self.process
        if proc is None:
            return None
        steps: list[Callable[[], Awaitable[None] | None]] = [
            lambda: self.meta({"type": "quit"}), self._close_stdin,
            lambda: self._signal(signal.SIGTERM), lambda: self._signal(signal.SIGKILL)]
        for step in steps:
            if proc.returncode is not None:
                break
            done = step()
            if done is not None:
                await done
            try:
                await asyncio.wait_for(proc.wait(), QUIT_GRACE if step is steps[0] else TERM_GRACE)
            except asyncio.TimeoutError:
                continue
        if self._reader is not None:
            self._reader.cancel()
        return proc.returncode

    async def _close_stdin(self) -> None:
        proc = self.process
        if proc is not None and proc.stdin is not None:
            proc.stdin.close()

    def _signal(self, signum: int) -> None:
        proc = self.process
        if proc is not None and proc.returncode is None:
            try:
                os.kill(proc.pid, signum)  # its pid only: never the session it started
            except ProcessLookupError:
                pass
