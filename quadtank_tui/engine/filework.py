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
same order, deterministic.  While a driver drives inline (no thread, an injected
time source: `quadtank run` as fast as possible) it holds the log rows as the
thread's batches are held (:meth:`FileWorker.hold`): one write(2) of the rows of
a BATCH_WINDOW, not one a row (a write of its own is a sizeable share of a
sample's time at x1000), and the same promise as the thread's: a killed process loses at most the
rows of the last millisecond.

Log rows go in batches (:meth:`FileWorker.submit_batched`): a row that comes within
BATCH_WINDOW of the last hand-off is held, in order, and handed on with the next
one, or when the driver is about to wait a millisecond or more
(:meth:`FileWorker.flush`; engine/driver.py, FLUSH_BEFORE).  A row per
sample at 50 ms is handed on at once, as before; at x1000 (20,000 rows a second)
one job of about 20 rows a millisecond, written in one write(2), not 20 Futures,
queue puts, wake-ups of the thread and writes, which would cost the session
process about half its CPU a sample.
"""

from __future__ import annotations

import queue
import threading
import time
from concurrent.futures import Future
from typing import Any, Callable, TypeVar

T = TypeVar("T")

#: How long close() waits for the writes still queued (a hung disk must not hang the exit).
CLOSE_TIMEOUT = 30.0

#: Operations given to submit_batched within this many seconds of the last hand-off
#: to the thread are held and handed on together, s.
BATCH_WINDOW = 0.001

_Job = tuple[Callable[..., Any], tuple[Any, ...], "Future[Any]"]


class FileWorker:
    """Runs file operations in submission order, inline or on its own thread."""

    def __init__(self, name: str = "quadtank-files") -> None:
        self._name = name
        self._queue: queue.SimpleQueue[_Job | None] = queue.SimpleQueue()
        self._thread: threading.Thread | None = None
        self._closed = False
        self._batch: list[tuple[Callable[[list[Any]], object], Any]] = []
        self._handed = -float("inf")  # when the last batch went to the thread (time.monotonic)
        self._holding = False  # inline, batches held as on the thread (hold)

    @property
    def threaded(self) -> bool:
        return self._thread is not None

    @property
    def batches(self) -> bool:
        """submit_batched holds its items for a batch (on the thread, or held inline)."""
        return self._holding or self._thread is not None

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
        self.flush()  # what submit_batched holds goes first: the order kept
        if self._thread is None or self._closed or threading.current_thread() is self._thread:
            _run_one(fn, args, fut)
        else:
            self._queue.put((fn, args, fut))
        return fut

    def hold(self, on: bool) -> None:
        """Inline, hold the items of submit_batched as the thread's are held, and
        hand them on (run them) a BATCH_WINDOW at a time (on: an inline drive
        begins), or run what is held and each one at once again (off: it ends)."""
        if not on:
            self.flush()
        self._holding = on

    def submit_batched(self, fn: Callable[[list[Any]], object], item: Any) -> None:
        """Run ``fn([item, ...])`` after everything submitted before, without a Future:
        `fn` keeps its own failure (a log row's: LogSession.check).  On the thread,
        or inline while held (:meth:`hold`), the items of the same BATCH_WINDOW go
        to one call (the caller's thread, the one that samples, calls :meth:`flush`
        before it waits); otherwise inline `fn([item])` runs at once."""
        if not self._holding and (self._thread is None or self._closed
                                  or threading.current_thread() is self._thread):
            self.flush()
            _run_quietly(fn, [item])
            return
        self._batch.append((fn, item))
        if time.monotonic() - self._handed >= BATCH_WINDOW:
            self.flush()

    def flush(self) -> None:
        """Hand the operations held by submit_batched on now (to run inline if the
        thread is gone)."""
        if not self._batch:
            return
        batch, self._batch = self._batch, []
        self._handed = time.monotonic()
        if self._thread is None or self._closed or threading.current_thread() is self._thread:
            _run_batch(batch)
        else:
            self._queue.put((_run_batch, (batch,), Future()))

    def drain(self, timeout: float | None = None) -> bool:
        """Wait until everything submitted so far has run; False on a timeout."""
        self.flush()
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


def _run_quietly(fn: Callable[[list[Any]], object], items: list[Any]) -> None:
    try:
        fn(items)
    except Exception:  # noqa: BLE001, S110 - fn kept its failure (submit_batched)
        pass


def _run_batch(batch: list[tuple[Callable[[list[Any]], object], Any]]) -> None:
    """Each run of items for the same function in one call, in order."""
    i = 0
    while i < len(batch):
        fn = batch[i][0]
        j = i + 1
        while j < len(batch) and batch[j][0] == fn:
            j += 1
        _run_quietly(fn, [item for _, item in batch[i:j]])
        i = j


def _run_one(fn: Callable[..., T], args: tuple[Any, ...], fut: Future[T]) -> None:
    if not fut.set_running_or_notify_cancel():
        return
    try:
        result = fn(*args)
    except Exception as exc:  # noqa: BLE001 - the Future carries it to whoever asked
        fut.set_exception(exc)
    else:
        fut.set_result(result)
