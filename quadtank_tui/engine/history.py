"""Fixed-capacity ring buffers of every trend signal (M7).

One preallocated (capacity x signals) float array: appending a sample writes one row
and never allocates, so an 8-hour run at 50 ms uses the same memory as a minute.

One thread writes (the loop, or a session client's reader appending what its
session sent) and another may read (the UI).  The writer never waits for a reader:
it announces the row, writes it, then bumps the count of rows ever written.  A
reader copies what it saw as complete and afterwards drops the rows the writer may
have overwritten meanwhile, so a reader can lose a few of its oldest rows to a fast
writer but never gets a half-written one.  A clear (Reset) bumps a generation
counter twice, seqlock style; a reader that sees it change starts over.  Only the
display could be wrong; the loop's own data and its log are written by the loop
alone.
"""

from __future__ import annotations

import struct
import time
from typing import Mapping, Sequence

import numpy as np

from quadtank_tui.engine.handle import SIGNALS

#: Default capacity: 1 h at 100 ms, 30 min at 50 ms.
DEFAULT_CAPACITY = 36_000
#: The trends need at least this many samples of every signal.
MIN_CAPACITY = 5_000
#: Header words: rows ever written, absolute index of the first row kept (moves on
#: clear), clear generation (odd while a clear is under way), rows begun (one more
#: than written while a row is being written).
HEADER_WORDS = 4
_TOTAL, _START, _GEN, _BEGUN = range(HEADER_WORDS)


def check_capacity(capacity: int) -> int:
    if capacity < MIN_CAPACITY:
        raise ValueError(f"history capacity must be >= {MIN_CAPACITY} samples, got {capacity}")
    return int(capacity)


class History:
    """The last `capacity` samples of :data:`SIGNALS` ("t" first)."""

    def __init__(self, capacity: int = DEFAULT_CAPACITY) -> None:
        self.capacity = check_capacity(capacity)
        self._hdr = np.zeros(HEADER_WORDS, dtype=np.int64)
        self._buf = np.zeros((self.capacity, len(SIGNALS)), dtype=float)
        #: The writer's own copy of _hdr[_TOTAL] (a Python int: reading the array costs more).
        self._total = 0
        # The writer's views of the same memory: a row packed into the buffer's bytes
        # and the header's words set through a memoryview cost less than numpy's item
        # assignment (the same float64 bits).
        self._row = struct.Struct(f"{len(SIGNALS)}d")
        self._bytes = self._buf.data.cast("B")
        self._words = self._hdr.data

    def __len__(self) -> int:
        total, start = int(self._hdr[_TOTAL]), int(self._hdr[_START])
        return min(total - start, self.capacity)

    @property
    def nbytes(self) -> int:
        """Memory held by the samples (constant)."""
        return self._buf.nbytes

    # --- the writer (the loop) ---------------------------------------------------------------

    def append(self, row: Sequence[float]) -> None:
        """One sample, values in :data:`SIGNALS` order."""
        total = self._total
        words = self._words
        words[_BEGUN] = total + 1  # the oldest row is about to go
        self._row.pack_into(self._bytes, (total % self.capacity) * self._row.size, *row)
        words[_TOTAL] = self._total = total + 1  # published only once the row is whole

    def extend(self, rows: np.ndarray) -> None:
        """Many samples at once (a client catching up with its session), oldest first;
        rows beyond the capacity push the oldest out, as one append each would."""
        rows = np.asarray(rows, dtype=float).reshape(-1, len(SIGNALS))[-self.capacity:]
        total, n = int(self._hdr[_TOTAL]), len(rows)
        if n == 0:
            return
        self._hdr[_BEGUN] = total + n
        idx = (total + np.arange(n)) % self.capacity
        self._buf[idx] = rows
        self._hdr[_TOTAL] = self._total = total + n

    def since(self, index: int) -> tuple[np.ndarray, int, int]:
        """(rows with absolute index >= `index` still kept, rows ever written, clear
        generation): what a session sends its clients after each publication.  For
        the writer's own thread (no concurrent append)."""
        total, start, gen = int(self._hdr[_TOTAL]), int(self._hdr[_START]), int(self._hdr[_GEN])
        lo = max(index, start, total - self.capacity)
        if lo >= total:
            return self._buf[:0].copy(), total, gen
        a, b = lo % self.capacity, total % self.capacity
        rows = self._buf[a:b].copy() if a < b else np.concatenate((self._buf[a:], self._buf[:b]))
        return rows, total, gen

    def clear(self) -> None:
        hdr = self._hdr
        hdr[_GEN] += 1
        hdr[_START] = hdr[_TOTAL]
        hdr[_GEN] += 1

    # --- readers (any thread) ---------------------------------------------------

    def last(self, seconds: float | None = None) -> Mapping[str, np.ndarray]:
        """Copies of the samples with t >= t_last - seconds (all kept if None).

        One copy, of the window only, column by column: the screen asks for its
        trends' window 20 times a second out of a ring of an hour."""
        cols = self._consistent_columns(seconds)
        cols.flags.writeable = False
        return {name: cols[i] for i, name in enumerate(SIGNALS)}

    def _first_since(self, lo: int, total: int, seconds: float) -> int:
        """The absolute index of the first row in [lo, total) whose t is at least the
        newest t less `seconds` (t rises along the ring, in two pieces once it wraps)."""
        cap, t = self.capacity, self._buf[:, 0]
        edge = t[(total - 1) % cap] - seconds
        a = lo % cap
        head = min(total - lo, cap - a)  # rows lo.. up to the end of the array
        i = int(np.searchsorted(t[a:a + head], edge, side="left"))
        if i < head:
            return lo + i
        return lo + head + int(np.searchsorted(t[:total - lo - head], edge, side="left"))

    def _consistent_columns(self, seconds: float | None, attempts: int = 100) -> np.ndarray:
        """(len(SIGNALS), n) C-ordered: each signal a contiguous row."""
        hdr, cap = self._hdr, self.capacity
        for attempt in range(attempts):
            last = attempt == attempts - 1  # a writer that died half-way: take what is there
            gen = int(hdr[_GEN])
            if gen & 1 and not last:  # a clear is under way: it takes a few stores
                time.sleep(0)
                continue
            total, start = int(hdr[_TOTAL]), int(hdr[_START])
            lo = min(max(start, total - cap), total)
            if seconds is not None and total > lo:
                lo = self._first_since(lo, total, seconds)
            a, b = lo % cap, total % cap
            if total - lo == 0:
                cols = np.empty((len(SIGNALS), 0))
            elif a < b:
                cols = self._buf[a:b].T.copy()
            else:  # (np.concatenate would keep the transposes' column order)
                cols = np.empty((len(SIGNALS), total - lo))
                cols[:, :cap - a] = self._buf[a:].T
                cols[:, cap - a:] = self._buf[:b].T
            if int(hdr[_GEN]) != gen and not last:
                continue
            # Rows the writer began while we copied may hold newer samples: drop
            # them from the old end.
            safe_lo = int(hdr[_BEGUN]) - cap
            return cols[:, max(0, safe_lo - lo):]
        raise AssertionError("unreachable: the last attempt returns")
