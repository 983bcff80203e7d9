"""Memory the loop process and the UI process both map: the trends and the snapshot.

When the loop runs in its own process (:mod:`engine.process`), what the UI reads
every frame must not cost the loop a pipe write it could block on.  The loop writes
its ring buffers and its latest snapshot into one shared block, without locks (a
reader can never hold the writer up); the UI copies them out when it redraws.

The block is a file in /dev/shm (the temporary folder where there is none) that
both processes map and that is unlinked as soon as both have it: whichever process
dies, nothing is left behind.
"""

from __future__ import annotations

import mmap
import os
import pickle
import tempfile
import threading
import time
import zlib
from dataclasses import replace
from typing import Callable

import numpy as np

from quadtank_tui.core.parameters import Parameters
from quadtank_tui.engine.handle import SIGNALS
from quadtank_tui.engine.history import HEADER_WORDS, History
from quadtank_tui.engine.snapshot import Snapshot

#: Room for a pickled Parameters (about 2 KB today) and a Snapshot without them (0.6 KB).
PARAMS_BYTES = 256 * 1024
SNAPSHOT_BYTES = 64 * 1024
_ALIGN = 64


def _shm_dir() -> str:
    return "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else tempfile.gettempdir()


class SharedBlock:
    """A file-backed memory map of `size` bytes, cut into aligned numpy views."""

    def __init__(self, path: str, size: int, fd: int | None = None) -> None:
        """Map the file at `path` (or the open `fd`, which is closed: the map keeps
        its own)."""
        self.path = path
        if fd is None:
            fd = os.open(path, os.O_RDWR)
        try:
            self._mm = mmap.mmap(fd, size)
        finally:
            os.close(fd)
        self.size = size
        self._offset = 0

    @classmethod
    def create(cls, size: int) -> SharedBlock:
        fd, path = tempfile.mkstemp(prefix="quadtank-", suffix=".shm", dir=_shm_dir())
        try:
            try:
                os.ftruncate(fd, size)  # zero-filled
            except BaseException:
                os.close(fd)
                raise
            return cls(path, size, fd)  # which closes fd
        except BaseException:
            os.unlink(path)
            raise

    def array(self, shape: tuple[int, ...], dtype: type) -> np.ndarray:
        """The next `shape` x `dtype` region of the block (the same order in every
        process gives the same regions)."""
        count = int(np.prod(shape))
        nbytes = count * np.dtype(dtype).itemsize
        start = -(-self._offset // _ALIGN) * _ALIGN
        if start + nbytes > self.size:
            raise ValueError(f"shared block of {self.size} bytes is too small")
        self._offset = start + nbytes
        return np.ndarray(shape, dtype=dtype, buffer=self._mm, offset=start)

    def unlink(self) -> None:
        """Remove the name; the memory lives on while a process maps it."""
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass


class BytesSlot:
    """One byte string at a time, seqlock style: the writer makes the sequence odd,
    writes, makes it even; a reader keeps a copy only if the sequence was even and
    unchanged around it and the copy's CRC-32 is the one written with it (which
    also catches stores seen out of order on weakly ordered CPUs)."""

    HEADER_WORDS = 3  # sequence, length, crc32

    def __init__(self, header: np.ndarray, data: np.ndarray) -> None:
        self._hdr = header
        self._data = data   # uint8[capacity]

    def write(self, payload: bytes) -> int:
        """Store `payload`; returns its (even) sequence number."""
        n = len(payload)
        if n > len(self._data):
            raise ValueError(f"{n} bytes do not fit a shared slot of {len(self._data)}")
        seq = int(self._hdr[0])
        seq += seq & 1  # a writer before us died half-way: carry on from even
        self._hdr[0] = seq + 1
        self._data[:n] = np.frombuffer(payload, dtype=np.uint8)
        self._hdr[1] = n
        self._hdr[2] = zlib.crc32(payload)
        self._hdr[0] = seq + 2
        return seq + 2

    def read(self, attempts: int = 100) -> tuple[int, bytes] | None:
        """(sequence, payload), or None if nothing whole could be read (never written,
        or the writer died in the middle of a write)."""
        for _ in range(attempts):
            seq = int(self._hdr[0])
            if seq == 0:
                return None
            if not seq & 1:
                n, crc = int(self._hdr[1]), int(self._hdr[2])
                payload = self._data[:n].tobytes()
                if int(self._hdr[0]) == seq and zlib.crc32(payload) == crc:
                    return seq, payload
            time.sleep(0)
        return None


class SharedState:
    """The regions of one block: the ring buffers, the parameters in force, the
    latest snapshot (without its parameters, which change far less often)."""

    def __init__(self, block: SharedBlock, capacity: int) -> None:
        self.block = block
        self.capacity = capacity
        hist_header = block.array((HEADER_WORDS,), np.int64)
        hist_rows = block.array((capacity, len(SIGNALS)), np.float64)
        self.history = History(capacity, header=hist_header, rows=hist_rows)
        slot_header = (BytesSlot.HEADER_WORDS,)
        self.params = BytesSlot(block.array(slot_header, np.int64), block.array((PARAMS_BYTES,), np.uint8))
        self.snapshot = BytesSlot(block.array(slot_header, np.int64), block.array((SNAPSHOT_BYTES,), np.uint8))

    @staticmethod
    def size(capacity: int) -> int:
        words = (HEADER_WORDS * 8 + capacity * len(SIGNALS) * 8 + 2 * BytesSlot.HEADER_WORDS * 8
                 + PARAMS_BYTES + SNAPSHOT_BYTES)
        return words + 8 * _ALIGN

    @classmethod
    def create(cls, capacity: int) -> SharedState:
        return cls(SharedBlock.create(cls.size(capacity)), capacity)

    @classmethod
    def attach(cls, path: str, capacity: int) -> SharedState:
        return cls(SharedBlock(path, cls.size(capacity)), capacity)


class SnapshotWriter:
    """The loop's publisher: each snapshot goes to the shared slot, at most every
    `min_interval` wall seconds (a 1000x virtual clock publishes 20000 a second; the
    UI reads 20).  :meth:`flush` writes the one held back.  Thread-safe."""

    def __init__(self, state: SharedState, *, min_interval: float = 0.002,
                 now: Callable[[], float] = time.monotonic) -> None:
        self._state = state
        self._min = min_interval
        self._now = now
        self._lock = threading.Lock()
        self._pending: Snapshot | None = None
        self._last = -float("inf")
        self._params: Parameters | None = None
        self._params_seq = 0

    def __call__(self, snap: Snapshot) -> None:
        with self._lock:
            self._pending = snap
            if self._now() - self._last >= self._min:
                self._write()

    def flush(self) -> None:
        with self._lock:
            self._write()

    def _write(self) -> None:
        snap = self._pending
        if snap is None:
            return
        self._pending = None
        if snap.params is not self._params:
            self._params_seq = self._state.params.write(pickle.dumps(snap.params, protocol=5))
            self._params = snap.params
        # The parameters travel in their own slot; the reader puts them back.
        record = (self._params_seq, replace(snap, params=None))  # type: ignore[arg-type]  # None only in transit
        self._state.snapshot.write(pickle.dumps(record, protocol=5))
        self._last = self._now()


class SnapshotReader:
    """The UI's side: the latest whole snapshot, unpickled once per new sequence and
    with the same Parameters object for as long as they do not change (the screens
    redraw parameter tables only when it does)."""

    def __init__(self, state: SharedState) -> None:
        self._state = state
        self._seq = 0
        self._snap: Snapshot | None = None
        self._params: Parameters | None = None
        self._params_seq = 0

    def read(self) -> Snapshot | None:
        """The newest snapshot (None before the first)."""
        got = self._state.snapshot.read()
        if got is None or got[0] == self._seq:
            return self._snap
        seq, payload = got
        params_seq, snap = pickle.loads(payload)
        if params_seq != self._params_seq:
            params = self._state.params.read()
            if params is None or params[0] != params_seq:
                return self._snap  # newer parameters than this snapshot's: take the next
            self._params, self._params_seq = pickle.loads(params[1]), params_seq
        self._seq, self._snap = seq, replace(snap, params=self._params)
        return self._snap

