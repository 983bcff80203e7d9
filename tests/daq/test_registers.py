"""The register codec both ends share: FLOAT32 in either word order, scaled integers."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from quadtank_tui.daq.registers import Register, block, decode, encode

F_BIG = Register("input", 0, "float32", "big")
F_LITTLE = Register("input", 0, "float32", "little")


def test_float32_words_are_ieee754_high_word_first() -> None:
    # 1.0f = 0x3F800000; 6.2f = 0x40C66666 (IEEE 754 single precision)
    assert encode(F_BIG, 1.0) == [0x3F80, 0x0000]
    assert encode(F_BIG, 6.2) == [0x40C6, 0x6666]
    assert encode(F_LITTLE, 6.2) == [0x6666, 0x40C6]
    assert decode(F_BIG, [0x40C6, 0x6666]) == pytest.approx(6.2, abs=1e-6)


@given(st.floats(min_value=-10.5, max_value=10.5))
def test_float32_round_trip(v: float) -> None:
    for reg in (F_BIG, F_LITTLE):
        assert decode(reg, encode(reg, v)) == pytest.approx(v, rel=1e-7, abs=1e-37)


def test_scaled_integers_round_and_saturate() -> None:
    s16 = Register("holding", 10, "int16", scale=0.001)
    assert encode(s16, 6.2) == [6200]
    assert encode(s16, -1.0) == [(-1000) & 0xFFFF]
    assert decode(s16, [(-1000) & 0xFFFF]) == pytest.approx(-1.0)
    assert encode(s16, 99.0) == [32767]
    u16 = Register("holding", 10, "uint16", scale=10 / 65535)
    assert encode(u16, -2.0) == [0]
    assert decode(u16, [65535]) == pytest.approx(10.0)
    with pytest.raises(ValueError):
        encode(u16, math.nan)


def test_one_request_covers_neighbouring_channels_only() -> None:
    ains = [Register("input", 2 * i) for i in range(4)]
    assert block(ains) == (0, 8)
    assert block([Register("input", 0), Register("holding", 2)]) is None
    assert block([Register("input", 0), Register("input", 200)]) is None
    assert block([Register("input", 0), Register("input", 4)]) is None  # a gap: 2-3 may not exist
    assert block([Register("holding", 7, "int16"), Register("holding", 6, "int16")]) == (6, 2)
