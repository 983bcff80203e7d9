"""Ending the TUI when its terminal goes away.

A terminal can go away without the TUI being told: `ssh -t host 'make run'` whose
link drops, or a tmux window killed, hangs the terminal up, and the kernel sends
SIGHUP only to the session leader (make, or the shell), which may keep it to
itself.  Textual's input thread then reads end-of-file forever (75 % CPU) and the
loop goes on driving the process with nobody watching.  SIGTERM (a `kill`, a
systemd stop) and SIGHUP would otherwise end the program where it stands, with the
terminal left in the alternate screen and mouse tracking on.

:class:`TerminalWatch` notices all three - the terminal hung up (POLLHUP on stdin
or stdout, which poll reports without reading a byte of the user's input), SIGHUP,
SIGTERM - and asks the app to exit in order, as its Exit does (the terminal put
back as it was; the caller then stops the loop: pumps at 0, the log kept).  If the
app has not closed within `grace` seconds (its writer blocked on a dead terminal,
say, or a machine too busy to close it that fast), the watch puts the terminal back
itself, stops the engine, says why the program stopped (the line the caller would
have printed: `farewell`) and ends the process: the program never outlives its
terminal by more than about a second, and never ends without saying why.
"""

from __future__ import annotations

import os
import select
import signal
import sys
import threading
from types import FrameType
from typing import Any, Callable, Sequence

#: Seconds the app has to close in order before the watch ends the program itself.
GRACE = 0.8
#: Seconds the watch's own stop of the engine may take before the process ends anyway
#: (the session process of a `--no-session` TUI stops by itself, pumps at 0, when
#: this process is gone: its lifeline closes).
STOP_GRACE = 3.0
#: Exit status after a hang-up: the shell's for SIGHUP.
HANGUP_STATUS = 128 + signal.SIGHUP
#: What a Textual app turns on and must turn off again: mouse tracking (1000, 1002,
#: 1003, SGR 1006, urxvt 1015), focus events, bracketed paste, the kitty keyboard
#: protocol; then the main screen back and the cursor shown.
RESTORE_SEQUENCE = ("\x1b[?1000l\x1b[?1002l\x1b[?1003l\x1b[?1006l\x1b[?1015l\x1b[?1004l"
                    "\x1b[?2004l\x1b[<u\x1b[?1049l\x1b[?25h")


class TerminalWatch:
    """request_exit(status) : asks the app to exit with `status`; called from the
        watch's thread, so it must be thread-safe (QuadTankApp.exit_soon).
    stop_engine() : stops the loop (pumps at 0); used only when the app does not
        close within `grace`.
    fds : the terminal's file descriptors to watch for a hang-up.
    farewell(reason) : says why the program stopped ("SIGTERM", "the terminal hung
        up"), as the caller does after an exit in order; used only when the app does
        not close within `grace` (the process then ends without coming back).
    """

    def __init__(self, request_exit: Callable[[int], None], stop_engine: Callable[[], None], *,
                 fds: Sequence[int] = (0, 1), grace: float = GRACE,
                 stop_signals: Sequence[signal.Signals] = (signal.SIGHUP, signal.SIGTERM),
                 end_process: Callable[[int], None] = os._exit,
                 farewell: Callable[[str], None] = lambda reason: None) -> None:
        self._request_exit = request_exit
        self._stop_engine = stop_engine
        self._farewell = farewell
        self._fds = tuple(fds)
        self._grace = grace
        self._signals = tuple(stop_signals)
        self._end_process = end_process
        #: Why the TUI is ending ("SIGTERM", "the terminal hung up"), None while it is not.
        self.reason: str | None = None
        #: The exit status that goes with `reason`.
        self.status = 0
        self._signum: int | None = None
        self._closed = threading.Event()  # the app has closed (or the watch is done)
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_w, False)
        #: The handlers to restore: what signal.signal returned (None: one not set from Python).
        self._previous: dict[int, Callable[[int, FrameType | None], Any] | int | signal.Handlers | None] = {}
        self._thread: threading.Thread | None = None
        self._attrs = _terminal_attrs(self._fds)

    # --- lifetime ------------------------------------------------------------------------

    def start(self) -> None:
        """Install the signal handlers (main thread only) and start watching."""
        for sig in self._signals:
            self._previous[sig] = signal.signal(sig, self._on_signal)
        self._thread = threading.Thread(target=self._watch, name="quadtank-terminal-watch", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """The app has closed: restore the signal handlers, stop watching."""
        self._closed.set()
        for sig, previous in self._previous.items():
            # None (a handler installed outside Python) cannot be passed back: the default then
            signal.signal(sig, signal.SIG_DFL if previous is None else previous)
        self._previous.clear()
        self._poke()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=1.0)
        for fd in (self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass

    # --- the watch -------------------------------------------------------------------------

    def _on_signal(self, signum: int, frame: object) -> None:
        # In a signal handler only a flag and a byte: the thread does the rest.
        if self._signum is None:
            self._signum = signum
        self._poke()

    def _poke(self) -> None:
        try:
            os.write(self._wake_w, b"!")
        except OSError:  # full (it is already awake) or closed
            pass

    def _watch(self) -> None:
        poller = select.poll()
        for fd in self._fds:
            poller.register(fd, 0)  # event mask 0: only POLLHUP, POLLERR, POLLNVAL come back
        poller.register(self._wake_r, select.POLLIN)
        while not self._closed.is_set():
            try:
                events = poller.poll()
            except InterruptedError:
                continue
            hung_up = False
            for fd, mask in events:
                if fd == self._wake_r:
                    continue
                if mask & select.POLLNVAL:  # closed under us: nothing more to watch there
                    poller.unregister(fd)
                elif mask & (select.POLLHUP | select.POLLERR):
                    hung_up = True
            if self._closed.is_set():
                return
            if self._signum is not None:
                name = signal.Signals(self._signum).name
                self._end(name, 128 + self._signum)
                return
            if hung_up:
                self._end("the terminal hung up", HANGUP_STATUS)
                return

    def _end(self, reason: str, status: int) -> None:
        self.reason, self.status = reason, status
        try:
            self._request_exit(status)
        except Exception:  # noqa: BLE001 - the fallback below still ends the program
            pass
        if self._closed.wait(self._grace):
            return
        # The app did not close in time: do what it would have done, then end.
        self.restore_terminal()
        stopper = threading.Thread(target=self._stop_engine, name="quadtank-stop", daemon=True)
        stopper.start()
        stopper.join(STOP_GRACE)
        try:  # (the app may have closed meanwhile: the caller's line may come too, or be cut by the end)
            self._farewell(reason)
        except Exception:  # noqa: BLE001 - a farewell that fails must not keep the process
            pass
        self._end_process(status)

    def restore_terminal(self) -> None:
        """The terminal's modes as they were before the app started, the alternate
        screen and mouse tracking off; nothing if the terminal is gone."""
        import termios

        for fd, attrs in self._attrs.items():
            try:
                termios.tcsetattr(fd, termios.TCSANOW, attrs)
            except (termios.error, OSError):
                pass
        for fd in self._fds:
            try:
                if os.isatty(fd):
                    os.write(fd, RESTORE_SEQUENCE.encode())
                    break
            except OSError:
                pass


def _terminal_attrs(fds: Sequence[int]) -> dict[int, list[Any]]:
    """The termios settings of each terminal among `fds`, before the app changes them."""
    if sys.platform == "win32":  # pragma: no cover - no termios there
        return {}
    import termios

    out: dict[int, list[Any]] = {}
    for fd in fds:
        try:
            if os.isatty(fd):
                out[fd] = termios.tcgetattr(fd)
        except (termios.error, OSError):
            pass
    return out
