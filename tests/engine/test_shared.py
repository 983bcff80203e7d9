"""The shared snapshot slot: whole payloads only, bounded when the writer died."""

from __future__ import annotations

import numpy as np
import pytest

from quadtank_tui.engine.shared import BytesSlot


def slot(capacity: int = 64) -> BytesSlot:
    return BytesSlot(np.zeros(BytesSlot.HEADER_WORDS, dtype=np.int64), np.zeros(capacity, dtype=np.uint8))


def test_a_payload_comes_back_whole_with_its_sequence() -> None:
    s = slot()
    assert s.read() is None  # never written
    assert s.write(b"first") == 2 and s.write(b"second!") == 4
    assert s.read() == (4, b"second!")


def test_a_torn_payload_is_refused_and_a_dead_writer_costs_a_bounded_wait() -> None:
    s = slot()
    s.write(b"abcdef")
    s._data[0] = ord("X")  # data changed without a write: the CRC no longer matches
    assert s.read(attempts=3) is None
    s._hdr[0] += 1  # a writer killed half-way leaves the sequence odd
    assert s.read(attempts=3) is None
    assert s.write(b"again") % 2 == 0 and s.read() is not None  # the next writer recovers


def test_an_oversized_payload_is_refused_with_the_sizes() -> None:
    with pytest.raises(ValueError, match="65 bytes do not fit a shared slot of 64"):
        slot().write(b"x" * 65)
