"""Fixed-capacity ring buffers of every trend signal (M7).

One preallocated (capacity x signals) float array: appending a sample writes one row
and never allocates, so an 8-hour run at 50 ms uses the same memory as a minute.
Readers (the UI's trend timer, on another thread) get copies of the last N seconds,
oldest first, taken under a lock so a row is never half-written.
"""

from __future__ import annotations

import threading
from typing import Mapping, Sequence

import numpy as np

from quadtank_tui.engine.handle import SIGNALS

#: Default capacity: 1 h at 100 ms, 30 min at 50 ms.
DEFAULT_CAPACITY = 36_000
#: The trends need at least this many samples of every signal (issue 5).
MIN_CAPACITY = 5_000


class History:
    """The last `capacity` samples of :data:`SIGNALS` ("t" first)."""

    def __init__(self, capacity: int = DEFAULT_CAPACITY) -> None:
        if capacity < MIN_CAPACITY:
            raise ValueError(f"history capacity must be >= {MIN_CAPACITY} samples, got {capacity}")
        self.capacity = int(capacity)
        self._buf = np.zeros((self.capacity, len(SIGNALS)), dtype=float)
        self._next = 0      # row the next sample goes to
        self._count = 0     # rows filled (<= capacity)
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return self._count

    @property
    def nbytes(self) -> int:
        """Memory held by the samples (constant)."""
        return self._buf.nbytes

    def append(self, row: Sequence[float]) -> None:
        """One sample, values in :data:`SIGNALS` order."""
        with self._lock:
            self._buf[self._next] = row
            self._next = (self._next + 1) % self.capacity
            if self._count < self.capacity:
                self._count += 1

    def clear(self) -> None:
        with self._lock:
            self._next = 0
            self._count = 0

    def last(self, seconds: float | None = None) -> Mapping[str, np.ndarray]:
        """Copies of the samples with t >= t_last - seconds (all kept if None)."""
        with self._lock:
            n = self._count
            if n == self.capacity:
                rows = np.concatenate((self._buf[self._next:], self._buf[: self._next]))
            else:
                rows = self._buf[:n].copy()
        if seconds is not None and n:
            t = rows[:, 0]
            rows = rows[np.searchsorted(t, t[-1] - seconds, side="left"):]
        out = {}
        for i, name in enumerate(SIGNALS):
            col = np.ascontiguousarray(rows[:, i])
            col.flags.writeable = False
            out[name] = col
        return out
