"""The DAQ's own hardware watchdog: what a configuration declares, and the writes that arm it.

A device with a watchdog sets its outputs to a safe value by itself when nobody has
talked to it for a timeout: the one protection left when the computer driving the
rig hangs, is suspended or dies.  A configuration declares it in a `watchdog:`
section (daq/config.py reads it; the LabJack preset declares the T-series' own):

- `enable`: the register written 1 to arm it and 0 to disarm it (written 0 first
  while the others are configured: a LabJack refuses them while it is on);
- `timeout_register`: the timeout, in counts of `scale` seconds (a LabJack's whole
  seconds: a timeout is rounded up to what the register can hold);
- `outputs`: per pump output, the register holding the value it is set to on a
  timeout (written with the volts that stop its pump) and, optionally, the
  register switching that action on (written 1);
- `feed` (optional): a register whose write clears the timer (other traffic
  does on a LabJack unless it is strict);
- `strict_enable`, `strict_key` (optional, together, with `feed`): strict mode.
  Armed strict with a key chosen per run, only a write of that key to `feed`
  clears the timer: another client's reads, or `quadtank daq check`, no longer
  keep it quiet once this program and its guard are gone (without them, any
  Modbus traffic feeds it);
- `timeout`: `auto`, or the least timeout in seconds.

The timeout armed is a few samples: at least 2 TSamp and at least 1 s (the
least a LabJack takes), and at least the configured one.  The virtual rig
(daq/rig.py) implements the same registers and behaviour.  Pure data: no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from quadtank_tui.daq.registers import Register

#: The least timeout armed, s (LabJack T-series: "as low as 1 second").
MIN_TIMEOUT_S = 1.0
#: The least timeout in sampling times: one late sample must not trip it.
MIN_SAMPLES = 2.0


@dataclass(frozen=True)
class OutputAction:
    """What the watchdog does to one pump output on a timeout."""

    output: str                  # the output's name (DAC0)
    value: Register              # holds the value (volts) the output is set to
    enable: Register | None = None  # written 1 to switch the action on (None: always on)


@dataclass(frozen=True)
class Watchdog:
    """A device's watchdog as its configuration declares it."""

    enable: Register
    timeout_register: Register
    actions: tuple[OutputAction, ...]
    feed: Register | None = None
    #: the least timeout, s (0: `auto`, the sampling time's rule alone)
    timeout: float = 0.0
    #: strict mode (LabJack WATCHDOG_STRICT_ENABLE_DEFAULT / _KEY_DEFAULT); None: not declared
    strict_enable: Register | None = None
    strict_key: Register | None = None

    @property
    def strict(self) -> bool:
        """Only a write of the run's key to `feed` clears its timer."""
        return self.strict_enable is not None and self.strict_key is not None and self.feed is not None

    def timeout_for(self, tsamp: float) -> float:
        """The timeout armed for sampling time `tsamp`, s, as the register holds it."""
        return quantize_up(self.timeout_register, gap_limit(tsamp, self.timeout))

    def registers(self) -> list[tuple[str, Register]]:
        """(key, register) of every register it uses, for the overlap check."""
        regs = [("watchdog.enable", self.enable), ("watchdog.timeout_register", self.timeout_register)]
        for a in self.actions:
            regs.append((f"watchdog.outputs.{a.output}.value", a.value))
            if a.enable is not None:
                regs.append((f"watchdog.outputs.{a.output}.enable", a.enable))
        if self.feed is not None:
            regs.append(("watchdog.feed", self.feed))
        if self.strict_enable is not None and self.strict_key is not None:
            regs += [("watchdog.strict_enable", self.strict_enable), ("watchdog.strict_key", self.strict_key)]
        return regs

    def arm_writes(self, timeout: float, stop_volts: dict[str, float],
                   key: int = 0) -> list[tuple[str, Register, float]]:
        """The writes that arm it, in order: off, the timeout, strict mode with `key`
        (when declared), each output's safe value (`stop_volts`: output name -> the
        volts that stop its pump) and action, then on.  (what, register, value) each."""
        writes = [("disable", self.enable, 0.0), ("timeout", self.timeout_register, timeout)]
        if self.strict and self.strict_enable is not None and self.strict_key is not None:
            writes += [("strict mode", self.strict_enable, 1.0), ("strict key", self.strict_key, float(key))]
        for a in self.actions:
            writes.append((f"{a.output} value on timeout", a.value, stop_volts[a.output]))
            if a.enable is not None:
                writes.append((f"{a.output} action", a.enable, 1.0))
        writes.append(("enable", self.enable, 1.0))
        return writes

    def describe(self) -> str:
        """e.g. "enable at holding 61600, timeout at 61604, DAC0/DAC1 to their stop value"."""
        outs = "/".join(a.output for a in self.actions)
        least = "auto" if self.timeout == 0 else f"at least {self.timeout:g} s"
        mode = ("strict: only this program's feed with its key clears it" if self.strict
                else "non-strict: any Modbus traffic feeds it")
        return (f"enable at holding register {self.enable.address}, timeout ({least}) at "
                f"{self.timeout_register.address}, sets {outs} to stop their pumps; {mode}")


def gap_limit(tsamp: float, least: float = 0.0) -> float:
    """The longest silence the rig is allowed, s: at least 2 TSamp, 1 s and `least`.
    Longer, the device's watchdog (if any) has set the pumps to 0, and Active
    control must end rather than drive them again as if nothing happened."""
    return max(MIN_SAMPLES * tsamp, MIN_TIMEOUT_S, least)


def quantize_up(reg: Register, seconds: float) -> float:
    """`seconds` rounded up to what `reg` holds (whole counts of `scale` for the
    integer types; a LabJack's UINT32 seconds: 1.4 s -> 2 s)."""
    if reg.type == "float32":
        return seconds
    return math.ceil(seconds / reg.scale - 1e-9) * reg.scale
