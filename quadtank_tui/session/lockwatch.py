"""Noticing that a DAQ lock was taken over: an administrator may take a rig from a
program left running (`--take-over`); that program must then stop driving it
(pumps to 0) within a second or so, and say why.  A thread polls the lock file
(a few hundred bytes each, twice a second) and calls back once.  Another
program's record that did not win (a student's take-over, a later start:
session/lock.py) is told once per new finding (`on_note`), and the program drives on."""

from __future__ import annotations

import threading
from typing import Callable, Protocol


class Watched(Protocol):
    """A lock that says why it is no longer ours (session.lock.DaqLock, session.riglock.RigLock)."""

    def lost(self) -> str | None: ...

    @property
    def note(self) -> str | None: ...

#: Seconds between looks at the lock file.
INTERVAL = 0.5


class LockWatch:
    """Calls `on_lost(reason)` once, from its own thread, when `lock` is no longer
    this program's; `reason` says who took it (DaqLock.lost)."""

    def __init__(self, lock: Watched, on_lost: Callable[[str], None], *, interval: float = INTERVAL,
                 on_note: Callable[[str], None] | None = None) -> None:
        self._lock, self._on_lost, self._interval, self._on_note = lock, on_lost, interval, on_note
        self._stop = threading.Event()
        self.reason: str | None = None
        self._thread = threading.Thread(target=self._run, name="quadtank-lock-watch", daemon=True)

    def start(self) -> LockWatch:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)

    def _run(self) -> None:
        noted: str | None = None
        while not self._stop.wait(self._interval):
            try:
                reason = self._lock.lost()
            except OSError:  # the file unreadable for a moment: look again
                continue
            if reason is not None and not self._stop.is_set():
                self.reason = reason
                self._on_lost(reason)
                return
            note = self._lock.note
            if note is not None and note != noted and self._on_note is not None:
                self._on_note(note)
            noted = note
