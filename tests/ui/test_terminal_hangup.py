"""The TUI in a real pseudo-terminal: losing the terminal ends it, and its loop.

`quadtank --no-session` (the simulator, on a private session) runs in a pty as in a
terminal window.  The terminal then goes away the ways it does in a lab: hung up
under a shell that keeps the SIGHUP to itself (`ssh -t host 'make run'` whose link
drops, a tmux window killed: make is the session leader and only it is signalled),
SIGHUP, SIGTERM (SIGKILL, on a rig: tests/daq/test_active_hangup.py).  The whole process tree (the TUI, its private session)
must be gone within a bounded time, the session's private folder with it, the exit
status must say why, and a terminal that is still there must be given back as it
was (alternate screen and mouse tracking off).  A crash must exit non-zero.
"""

from __future__ import annotations

import fcntl
import os
import select
import shutil
import signal
import struct
import subprocess
import sys
import termios
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from quadtank_tui.session.runtime import list_sessions

pytestmark = [pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc and Linux ptys"),
              pytest.mark.wallclock]

ROOT = Path(__file__).parents[2]
#: Seconds the tree may take to go once the terminal is gone (the program's own bound
#: is about 1 s; the rest is margin for a loaded 2-core machine).
GONE_WITHIN = 15.0
#: Seconds the TUI may take to start (Textual, and a session process that imports numpy).
START_WITHIN = 90.0

ALT_ON, ALT_OFF = b"\x1b[?1049h", b"\x1b[?1049l"
MOUSE_OFF = (b"\x1b[?1000l", b"\x1b[?1003l", b"\x1b[?1006l")


class Tui:
    """`quadtank` (or `code` run by python) on a pty; `output` collects what it draws."""

    def __init__(self, tmp_path: Path, *, shell: bool = False, code: str | None = None,
                 args: tuple[str, ...] = ("--no-session",), env: dict[str, str] | None = None) -> None:
        (tmp_path / "params").mkdir()
        shutil.copy(ROOT / "params" / "default.par", tmp_path / "params" / "default.par")
        master, slave = os.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
        argv = [sys.executable, "-m", "quadtank_tui", *args] if code is None else [sys.executable, "-c", code]
        if shell:  # make's part: the session leader, which keeps SIGHUP and waits for its child
            argv = ["/bin/sh", "-c", 'trap ":" HUP; "$@"; exit $?', "sh", *argv]
        env = {**os.environ, "TERM": "xterm-256color", "COLUMNS": "120", "LINES": "40", **(env or {})}
        env.pop("TEXTUAL", None)
        self.proc = subprocess.Popen(
            argv, stdin=slave, stdout=slave, stderr=slave, cwd=tmp_path, env=env, close_fds=True,
            start_new_session=True,  # a session of its own, with the pty as its terminal
            preexec_fn=lambda: fcntl.ioctl(0, termios.TIOCSCTTY, 0),
        )
        os.close(slave)
        self.master: int | None = master
        self.output = bytearray()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        # Never block in read(): a read in progress holds the master open, so a
        # close() from another thread would not hang the terminal up until the TUI
        # next wrote something - and a paused TUI writes nothing.
        while True:
            fd = self.master
            if fd is None:
                return
            try:
                ready, _, _ = select.select([fd], [], [], 0.05)
                if not ready:
                    continue
                data = os.read(fd, 65536)
            except (OSError, ValueError):  # EIO: the other side is gone (or the master was closed)
                return
            if not data:
                return
            self.output += data

    def wait_started(self) -> int:
        """Wait for the screen and the session process; the TUI's pid (under the shell or not)."""
        deadline = time.monotonic() + START_WITHIN
        while time.monotonic() < deadline:
            tui = self.tui_pid()
            if tui is not None and ALT_ON in self.output and b"Pause" in self.output and _children(tui):
                return tui
            if self.proc.poll() is not None:
                break
            time.sleep(0.1)
        raise AssertionError(f"the TUI did not start: {bytes(self.output[-2000:])!r}")

    def started_session(self, runtime: Path) -> tuple[int, Any]:
        """Wait for the screen; (the TUI's pid, the one session in `runtime`, which
        it started and attached to)."""

        pid = self.wait_started()
        sessions = list_sessions(runtime)
        assert len(sessions) == 1, sessions
        assert self.master is not None
        return pid, sessions[0]

    def tui_pid(self) -> int | None:
        """The python process running the TUI: the Popen's or its child's."""
        if _cmdline(self.proc.pid)[:1] == ["/bin/sh"]:
            kids = _children(self.proc.pid)
            return kids[0] if kids else None
        return self.proc.pid

    def drained(self) -> bytes:
        """Everything the program wrote, once it has gone: the reader ends when the
        terminal's last writer has (EIO), however long a loaded machine takes."""
        self._reader.join(timeout=START_WITHIN)
        assert not self._reader.is_alive(), "the terminal was still written to"
        return bytes(self.output)

    def hang_up(self) -> None:
        """The terminal emulator (sshd, tmux) closes its side."""
        assert self.master is not None
        fd, self.master = self.master, None
        self._reader.join(timeout=5.0)  # out of select() first: then the close is the last
        os.close(fd)

    def kill(self) -> None:
        for pid in _tree(self.proc.pid):
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        if self.master is not None:
            os.close(self.master)
            self.master = None
        self.proc.wait(timeout=10)


def _cmdline(pid: int) -> list[str]:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace").split("\0")[:-1]
    except OSError:
        return []


def _children(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        return []
    return [int(p) for p in text.split()]


def _tree(pid: int) -> list[int]:
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        todo.extend(_children(p))
    return out


def _alive(pid: int) -> bool:
    """Running (a zombie waiting for its parent's wait counts as gone)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _wait_gone(pids: list[int], within: float) -> float:
    """Seconds until none of `pids` runs; fails after `within`."""
    start = time.monotonic()
    while any(_alive(p) for p in pids):
        if time.monotonic() - start > within:
            left = {p: _cmdline(p) for p in pids if _alive(p)}
            raise AssertionError(f"still running {within} s after the terminal went: {left}")
        time.sleep(0.02)
    return time.monotonic() - start


# On a busy machine the TUI may not close in order within terminal_watch.GRACE (0.8 s):
# the watch's fallback then ends it, saying why as well (at load 5-7 it had ended it
# without the line, in 3 of 6 runs of the wallclock tests on both cores).
@pytest.mark.parametrize("how, shell, status", [
    ("hang-up under a shell that keeps SIGHUP (make run)", True, 129),
    ("SIGHUP", False, 129),  # what the TUI gets from a hang-up when it leads the session
    ("SIGTERM", False, 143),
])
def test_losing_the_terminal_ends_the_tui_and_its_loop(tmp_path: Path, how: str, shell: bool,
                                                       status: int | None) -> None:
    tui = Tui(tmp_path, shell=shell)
    runtime = Path(os.environ["QUADTANK_RUNTIME"])
    try:
        pid = tui.wait_started()
        tree = _tree(tui.proc.pid)
        assert len(tree) == (3 if shell else 2), tree  # (sh,) the TUI, its private session
        assert list_sessions(runtime) == []  # private: not listed
        (folder,) = [p for p in (runtime / "users" / str(os.getuid())).iterdir() if p.name.startswith("private-")]
        if how.startswith("hang-up"):
            tui.hang_up()
        else:
            os.kill(pid, getattr(signal, how))
        took = _wait_gone(tree, GONE_WITHIN)
        print(f"{how}: the tree was gone {took:.2f} s after")
        code = tui.proc.wait(timeout=5)
        if status is not None:
            assert code == status
        assert not folder.exists()
        if tui.master is not None:  # the terminal is still there: given back as it was
            output = tui.drained()
            tail = output[output.rfind(ALT_ON):]
            assert ALT_OFF in tail and all(m in tail for m in MOUSE_OFF), tail[-400:]
            assert b"Traceback" not in tui.output
            assert f"quadtank: stopped: {how}".encode() in tui.output
    finally:
        tui.kill()


def test_a_crash_exits_non_zero_and_gives_the_terminal_back(tmp_path: Path) -> None:
    """An exception the app does not handle (here: in its on_mount) ends the TUI with
    status 1 (it was 0, and the shell could not tell), the terminal as it was."""
    code = ("import sys; import quadtank_tui.ui.app as a\n"
            "def boom(self): raise RuntimeError('boom')\n"
            "a.QuadTankApp.on_mount = boom\n"
            "from quadtank_tui.cli import main; sys.exit(main(['--no-session']))\n")
    tui = Tui(tmp_path, code=code)
    try:
        assert tui.proc.wait(timeout=START_WITHIN) == 1
        output = tui.drained()
        tail = output[output.rfind(ALT_ON):]
        assert ALT_OFF in tail and b"boom" in tail
    finally:
        tui.kill()


def test_when_the_app_does_not_close_the_watch_ends_the_program_itself() -> None:
    """The app's exit hangs (its writer blocked on a dead terminal, say): after the
    grace time the watch stops the engine itself, says why (the line the program
    prints after an exit in order) and ends the process with 129.  A pipe stands for
    the terminal: its other end closing is the hang-up."""
    from quadtank_tui.ui.terminal_watch import TerminalWatch

    r, w = os.pipe()
    asked: list[int] = []
    stopped, ended = threading.Event(), threading.Event()
    codes: list[int] = []

    def end(code: int) -> None:
        codes.append(code)
        ended.set()

    said: list[str] = []
    watch = TerminalWatch(asked.append, stopped.set, fds=(r,), grace=0.3, stop_signals=(),
                          end_process=end, farewell=said.append)
    watch.start()
    try:
        start = time.monotonic()
        os.close(w)
        assert ended.wait(10.0)
        took = time.monotonic() - start
        assert asked == [129] and stopped.is_set() and codes == [129]
        assert watch.reason == "the terminal hung up" and said == ["the terminal hung up"]  # why, said before the end
        assert 0.3 <= took < 5.0
    finally:
        watch.close()
        os.close(r)


def test_a_watch_closed_in_time_does_nothing_more() -> None:
    from quadtank_tui.ui.terminal_watch import TerminalWatch

    r, w = os.pipe()
    ended: list[int] = []
    watch = TerminalWatch(lambda code: None, lambda: None, fds=(r,), stop_signals=(), end_process=ended.append)
    watch.start()
    watch.close()
    os.close(w)
    time.sleep(0.2)
    assert ended == [] and watch.reason is None
    os.close(r)


def test_exit_is_prompt_with_a_hung_device(tmp_path: Path) -> None:
    """Active on a device that accepts and never answers (timeout 0.5 s, the LabJack
    preset's): the loop faults (pumps to 0, Pause); Run and Pause are pressed and
    wait for the hung sample, and Exit (q, Enter) meanwhile ends the program within
    a bounded time - a sample's timeouts and the last pumps-to-0 - with no
    traceback: the answers that come after the screen has gone are dropped.  It
    took 20-30 s and printed `NoMatches: No nodes match 'StatusLine'`."""
    import socket

    listener = socket.create_server(("127.0.0.1", 0))
    held: list[socket.socket] = []

    def accept_and_hold() -> None:  # the answers never come
        try:
            while True:
                held.append(listener.accept()[0])
        except OSError:  # the listener closed: the test is over
            return

    threading.Thread(target=accept_and_hold, daemon=True).start()
    port = listener.getsockname()[1]
    config = tmp_path / "hung.yaml"
    config.write_text((ROOT / "params" / "virtual-rig.yaml").read_text()
                      .replace("port: 5020", f"port: {port}").replace("timeout: 0.2", "timeout: 0.5"))
    code = f"import sys; from quadtank_tui.cli import main; sys.exit(main(['--no-session', '--daq', {str(config)!r}]))"
    tui = Tui(tmp_path, code=code)
    try:
        tui.wait_started()
        assert tui.master is not None
        os.write(tui.master, b"A")
        time.sleep(0.5)
        os.write(tui.master, b"r")
        deadline = time.monotonic() + 30
        while b"no answer within 0.5 s" not in tui.output and time.monotonic() < deadline:
            time.sleep(0.05)
        assert b"no answer within 0.5 s" in tui.output
        os.write(tui.master, b"rpq")  # Run and Pause wait for the hung sample; Exit meanwhile
        deadline = time.monotonic() + 30
        while b"Stop the loop and exit?" not in tui.output and time.monotonic() < deadline:
            time.sleep(0.05)
        t0 = time.monotonic()
        os.write(tui.master, b"\r")
        assert tui.proc.wait(timeout=30) == 0
        took = time.monotonic() - t0
        print(f"Exit with a hung device took {took:.2f} s")
        assert took < 10.0  # it took 20-30 s; room for a loaded machine
        output = tui.drained()
        assert b"Traceback" not in output and b"NoMatches" not in output
    finally:
        tui.kill()
        listener.close()
        for s in held:
            s.close()
