"""Ring buffers: fixed memory, last N seconds as read-only copies."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from quadtank_tui.engine.handle import SIGNALS
from quadtank_tui.engine.history import History


def test_wraps_at_capacity_and_keeps_the_newest_in_order() -> None:
    h = History(5000)
    nbytes = h.nbytes
    for k in range(12_345):
        h.append([k * 0.1] + [float(k)] * (len(SIGNALS) - 1))
    assert len(h) == 5000 and h.nbytes == nbytes
    data = h.last()
    assert set(data) == set(SIGNALS)
    assert data["y1"][0] == 12_345 - 5000 and data["y1"][-1] == 12_344
    assert np.all(np.diff(data["t"]) > 0)


def test_last_seconds_and_copies() -> None:
    h = History(5000)
    for k in range(100):
        h.append([k * 0.5] + [k] * (len(SIGNALS) - 1))
    recent = h.last(10.0)
    assert recent["t"][0] == pytest.approx(39.5) and recent["t"][-1] == pytest.approx(49.5)
    assert len(recent["u2"]) == 21
    with pytest.raises(ValueError):
        recent["y1"][0] = 1.0  # read-only
    h.append([50.0] + [7.0] * (len(SIGNALS) - 1))
    assert recent["y1"][-1] == 99  # a copy: later samples do not show up in it
    h.clear()
    assert len(h.last()["t"]) == 0


def test_capacity_of_at_least_5000_samples() -> None:
    with pytest.raises(ValueError):
        History(4999)


def write_rows(h: History, count: int, enough: threading.Event) -> None:
    """On another thread (a session client's reader): rows (k, k, k, ...) as fast as
    it can, a clear now and then, until `count` rows or `enough` is set."""
    for k in range(count):
        h.append([float(k)] * len(SIGNALS))
        if k % 64 == 63:  # let the reader in between rows, as a socket's reads do: unyielding,
            time.sleep(0)  # it wrote thousands a GIL slice and the reader saw mostly fresh rings
        if k % 7919 == 7918:
            h.clear()
            if enough.is_set():
                return


#: Reads of a ring being written that make the test's case: 500 copies of up to 5000
#: rows each (a fixed 3 million rows took 30,000 reads and 11-22 s on a loaded machine).
#: Copies of a nearly full ring (over 4000 of its 5000 rows) the test must see.
FULL_READS = 10
READS = 500


def test_a_reader_never_gets_a_torn_or_stale_row_while_another_thread_writes() -> None:
    """Every copy a reader takes of rows another thread is writing must be whole
    rows of consecutive k (the writer laps the 5000-row ring every few ms)."""
    h = History(5000)
    enough = threading.Event()
    writer = threading.Thread(target=write_rows, args=(h, 3_000_000, enough))
    writer.start()
    try:
        reads, full = 0, 0
        while writer.is_alive() or reads == 0:
            data = h.last()
            rows = np.column_stack([data[name] for name in SIGNALS])
            assert np.all(rows == rows[:, :1]), "a row mixes two samples"
            assert np.all(np.diff(rows[:, 0]) == 1.0), "rows out of order or skipped"
            reads += len(rows) > 0  # the copies of rows being written (not of the empty ring before)
            full += len(rows) > 4000
            if reads >= READS and full > FULL_READS:  # not before: a writer stopped early left 9 (CI, twice)
                enough.set()
    finally:
        enough.set()
        writer.join()
    assert reads > 100 and full > FULL_READS


def test_a_full_buffer_read_at_rest_gives_every_row() -> None:
    h = History(5000)
    for k in range(5000 * 3 + 17):
        h.append([float(k)] * len(SIGNALS))
    assert len(h.last()["t"]) == 5000 == len(h)


def test_a_writer_that_died_in_a_clear_does_not_hang_the_reader() -> None:
    h = History(5000)
    for k in range(10):
        h.append([float(k)] * len(SIGNALS))
    h._hdr[2] += 1  # the generation left odd, as by a writer killed between its stores
    assert list(h.last()["y1"]) == [float(k) for k in range(10)]


@pytest.mark.parametrize("rows", [300, 5000, 5000 + 1234, 3 * 5000 + 17])
def test_a_window_is_the_tail_of_the_whole_whether_the_ring_wrapped_or_not(rows: int) -> None:
    """last(seconds) copies only the window (the screen's 20 reads a second), and
    it is exactly the samples of the whole ring with t >= t_last - seconds."""
    h = History(5000)
    data = np.arange(rows, dtype=float)[:, None] * np.ones(len(SIGNALS))
    data[:, 0] *= 0.05
    h.extend(data)
    whole = h.last()
    for seconds in (0.0, 0.05, 0.07, 12.5, 249.95, 250.0, 1e9):
        window = h.last(seconds)
        keep = whole["t"] >= whole["t"][-1] - seconds
        for name in SIGNALS:
            assert np.array_equal(window[name], whole[name][keep]), (rows, seconds, name)
            assert window[name].flags.c_contiguous and not window[name].flags.writeable
