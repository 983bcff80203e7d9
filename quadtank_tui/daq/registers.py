"""Modbus register layouts of an analog channel and their encoding, both directions.

A channel's value (volts) lives in one or two 16-bit registers: an IEEE-754 FLOAT32
over two registers (a LabJack T-series, most gateways) in big or little word order,
or a scaled 16-bit integer (many PLCs: volts = count * scale).  A device's
configuration registers (its watchdog's: daq/watchdog.py) may also be UINT32, two
registers in the same word orders (a LabJack's WATCHDOG_TIMEOUT_S_DEFAULT).  The codec is plain
`struct` so the DAQ backend and the virtual rig share it and neither depends on the
helper names pymodbus has changed across 3.x releases.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Literal, Sequence

Table = Literal["input", "holding"]
RegType = Literal["float32", "int16", "uint16", "uint32"]
WordOrder = Literal["big", "little"]

TABLES: tuple[str, ...] = ("input", "holding")
TYPES: tuple[str, ...] = ("float32", "int16", "uint16")
#: The types of a configuration register (a watchdog's): the analog ones and UINT32.
SETTING_TYPES: tuple[str, ...] = TYPES + ("uint32",)
WORD_ORDERS: tuple[str, ...] = ("big", "little")
#: Modbus addresses are 16-bit.
MAX_ADDRESS = 0xFFFF

_INT_RANGE = {"int16": (-32768, 32767), "uint16": (0, 65535), "uint32": (0, 0xFFFFFFFF)}


@dataclass(frozen=True)
class Register:
    """Where and how one analog value is kept.

    table : "input" (read with function code 4) or "holding" (code 3, written with 16)
    address : first register, 0-based protocol address
    type : "float32" or "uint32" (2 registers), "int16" or "uint16" (1 register)
    word_order : the 2-register types; "big" = high word first (Modbus convention, LabJack)
    scale : volts per count for the integer types (ignored for float32)
    """

    table: Table
    address: int
    type: RegType = "float32"
    word_order: WordOrder = "big"
    scale: float = 1.0

    @property
    def count(self) -> int:
        """Number of 16-bit registers the value occupies."""
        return 2 if self.type in ("float32", "uint32") else 1

    @property
    def span(self) -> range:
        """The register addresses it occupies."""
        return range(self.address, self.address + self.count)

    def describe(self) -> str:
        """e.g. "input register 0 (float32)"; used in error messages."""
        return f"{self.table} register {self.address} ({self.type})"


def decode(reg: Register, words: Sequence[int]) -> float:
    """Volts from the `reg.count` registers read at `reg.address`."""
    if len(words) != reg.count:
        raise ValueError(f"{reg.describe()}: expected {reg.count} registers, got {len(words)}")
    if reg.type == "float32":
        hi, lo = (words[0], words[1]) if reg.word_order == "big" else (words[1], words[0])
        return struct.unpack(">f", struct.pack(">HH", hi & 0xFFFF, lo & 0xFFFF))[0]
    if reg.type == "uint32":
        hi, lo = (words[0], words[1]) if reg.word_order == "big" else (words[1], words[0])
        return ((hi & 0xFFFF) << 16 | (lo & 0xFFFF)) * reg.scale
    raw = words[0] & 0xFFFF
    if reg.type == "int16" and raw >= 0x8000:
        raw -= 0x10000
    return raw * reg.scale


def encode(reg: Register, volts: float) -> list[int]:
    """The registers that carry `volts` (integers saturate at their range)."""
    if not math.isfinite(volts):
        raise ValueError(f"{reg.describe()}: cannot encode {volts!r}")
    if reg.type == "float32":
        hi, lo = struct.unpack(">HH", struct.pack(">f", volts))
        return [hi, lo] if reg.word_order == "big" else [lo, hi]
    lo_count, hi_count = _INT_RANGE[reg.type]
    count = min(hi_count, max(lo_count, round(volts / reg.scale)))
    if reg.type == "uint32":
        hi, lo = count >> 16, count & 0xFFFF
        return [hi, lo] if reg.word_order == "big" else [lo, hi]
    return [count & 0xFFFF]


def block(regs: Sequence[Register]) -> tuple[int, int] | None:
    """(first address, register count) of one read covering exactly `regs`, or None
    when they sit in different tables, leave gaps (a device need not have the
    registers between them) or exceed one request (125 registers)."""
    if not regs or len({r.table for r in regs}) != 1:
        return None
    first = min(r.address for r in regs)
    end = max(r.address + r.count for r in regs)
    covered = {a for r in regs for a in r.span}
    if len(covered) != end - first or end - first > 125:
        return None
    return first, end - first
