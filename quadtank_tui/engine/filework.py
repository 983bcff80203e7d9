"""File operations in order, off the sampling path: one writer thread fed by a queue.

A sample must not wait for a disk: an fsync on a busy or networked disk can take
half a second, ten sampling periods at 50 ms.  The loop hands every write (log
rows, the log's LogOn/Save/Discard, a `.par` save) to a :class:`FileWorker` and
carries on; the worker runs them one after another, in the order given, on a thread
of its own, and each one's Future tells how it went.  The row-by-row promise of
files/log_writer.py holds there: each row is written (handed to the OS) as the worker gets
it, and fsynced at most a second after the last sync.

Until :meth:`FileWorker.start_thread` the worker runs each operation at once, on the
caller's thread (tests, headless runs on a virtual clock): the same results, the
same order, deterministic.
"""

from __future__ import annotations

import queue
import threading
from concurrent.futures import Future
from typing import Any, Callable, TypeVar

T = TypeVar("T")

#: How long close() waits for the writes still queued (a hung disk must not hang the exit).
CLOSE_TIMEOUT = 30.0

_Job = tuple[Callable[..., Any], tuple[Any, ...], "Future[Any]"]


class FileWorker:
    """Runs file operations in submission order, inline or on its own thread."""

    def __init__(self, name: str = "quadtank-files") -> None:
        self._name = name
        self._queue: queue.SimpleQueue[_Job | None] = queue.SimpleQueue()
        self._thread: threading.Thread | None = None
        self._closed = False

    @property
    def threaded(self) -> bool:
        return self._thread is not None

    def start_thread(self) -> None:
        """From now on, run the operations on the worker's own thread (idempotent)."""
        if self._thread is not None or self._closed:
            return
        self._thread = threading.Thread(target=self._run, name=self._name, daemon=True)
        self._thread.start()

    def submit(self, fn: Callable[..., T], *args: Any) -> Future[T]:
        """Run ``fn(*args)`` after everything submitted before; its Future has the
        return value or the exception."""
        fut: Future[T] = Future()
        if self._thread is None or self._closed or threading.current_thread() is self._thread:
            _run_one(fn, args, fut)
        else:
            self._queue.put((fn, args, fut))
        return fut

    def drain(self, timeout: float | None = None) -> bool:
        """Wait until everything submitted so far has run; False on a timeout."""
        if self._thread is None or not self._thread.is_alive() or threading.current_thread() is self._thread:
            return True
        marker: Future[None] = Future()
        self._queue.put((lambda: None, (), marker))
        try:
            marker.result(timeout)
        except TimeoutError:
            return False
        return True

    def close(self, timeout: float = CLOSE_TIMEOUT) -> bool:
        """Let the queued operations finish (up to `timeout` s), then end the thread;
        later operations run inline.  False if the disk did not finish in time."""
        if self._closed:
            return True
        done = self.drain(timeout)
        self._closed = True
        if self._thread is not None:
            self._queue.put(None)
            if done:
                self._thread.join(timeout)
        return done

    def _run(self) -> None:
        while True:
            job = self._queue.get()
            if job is None:
                return
            _run_one(*job)


def _run_one(fn: Callable[..., T], args: tuple[Any, ...], fut: Future[T]) -> None:
    if not fut.set_running_or_notify_cancel():
        return
    try:
        result = fn(*args)
    except Exception as exc:  # noqa: BLE001 - the Future carries it to whoever asked
        fut.set_exception(exc)
    else:
        fut.set_result(result)
