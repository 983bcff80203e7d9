"""The virtual rig says what it is: a block of registers with its pump amplifiers
and its level sensors, which a program compares with its DAQ file before it trusts
its readings or drives its pumps.

The virtual rig (daq/rig.py) applies its map's pump calibration to the DAC volts it
is written (pump volts = gain x DAC volts + offset) and its sensors read kc h (plus
its sensor model's offset): a DAQ file that assumes another amplifier (the LabJack
file's gain 2 against the preset's 1) makes the program believe 3 V while the rig
applies 1.5 V.  The block sits where a LabJack has nothing (holding registers from
IDENTITY_ADDRESS, FLOAT32 big-endian): a real device answers "illegal address",
and the comparison says it cannot be made.

Layout (FLOAT32 each): MAGIC, VERSION, pump gain 1, 2, pump offset 1, 2, tank gain
1..4 (level per volt), tank offset 1..4 (level), pump range high 1, 2 (V); a channel
the plant does not have is nan.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Sequence

IDENTITY_ADDRESS = 60500
MAGIC = 4711.0
VERSION = 1.0
FLOATS = 16
WORDS = 2 * FLOATS
#: relative agreement a gain or an offset needs (the file's decimals, not noise)
TOLERANCE = 1e-3


@dataclass(frozen=True)
class RigIdentity:
    """What a rig's block says: per pump gain and offset (pump V = gain x DAC V +
    offset), per tank gain and offset (level = gain x V + offset), the pump range."""

    pump_gains: tuple[float, ...]
    pump_offsets: tuple[float, ...]
    tank_gains: tuple[float, ...]
    tank_offsets: tuple[float, ...]
    pump_high: tuple[float, ...]

    def values(self) -> list[float]:
        def pad(xs: Sequence[float], n: int) -> list[float]:
            return [float(x) for x in xs][:n] + [math.nan] * (n - len(xs))

        return ([MAGIC, VERSION] + pad(self.pump_gains, 2) + pad(self.pump_offsets, 2) + pad(self.tank_gains, 4)
                + pad(self.tank_offsets, 4) + pad(self.pump_high, 2))

    def words(self) -> dict[int, int]:
        """The registers that serve it, by address."""
        out: dict[int, int] = {}
        for i, v in enumerate(self.values()):
            hi, lo = struct.unpack(">HH", struct.pack(">f", v))
            out[IDENTITY_ADDRESS + 2 * i] = hi
            out[IDENTITY_ADDRESS + 2 * i + 1] = lo
        return out


def decode_identity(words: Sequence[int]) -> RigIdentity | None:
    """The identity in `words` (WORDS registers from IDENTITY_ADDRESS), None when they
    do not start with the magic number (a device that is no virtual rig)."""
    if len(words) < WORDS:
        return None
    v = [struct.unpack(">f", struct.pack(">HH", words[2 * i] & 0xFFFF, words[2 * i + 1] & 0xFFFF))[0]
         for i in range(FLOATS)]
    if v[0] != MAGIC or v[1] != VERSION:
        return None

    def kept(xs: list[float]) -> tuple[float, ...]:
        return tuple(x for x in xs if not math.isnan(x))

    return RigIdentity(kept(v[2:4]), kept(v[4:6]), kept(v[6:10]), kept(v[10:14]), kept(v[14:16]))


def _differ(a: float, b: float, scale: float) -> bool:
    return abs(a - b) > TOLERANCE * max(abs(a), abs(b), scale)


def mismatches(rig: RigIdentity, pump_gains: Sequence[float], pump_offsets: Sequence[float],
               tank_gains: Sequence[float], tank_offsets: Sequence[float]) -> list[str]:
    """Where a DAQ file's calibration (the same four lists) is not the rig's, one
    phrase each ("pump1 gain 2 (the rig's 1)")."""
    out = []
    for what, mine, theirs, scale in (("pump{} gain", pump_gains, rig.pump_gains, 1.0),
                                      ("pump{} offset", pump_offsets, rig.pump_offsets, 1.0),
                                      ("tank{} gain", tank_gains, rig.tank_gains, 1.0),
                                      ("tank{} offset", tank_offsets, rig.tank_offsets, 1.0)):
        for i, (a, b) in enumerate(zip(mine, theirs)):
            if _differ(a, b, scale):
                out.append(f"{what.format(i + 1)} {a:g} (the rig's {b:g})")
    return out
