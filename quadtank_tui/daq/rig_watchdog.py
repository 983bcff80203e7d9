"""The virtual rig's watchdog: the registers a configuration declares, behaving as a LabJack's.

The rig serves the registers of its map's `watchdog:` (daq/watchdog.py; the LabJack
preset's are the T-series' own) and does what the device does: while enabled, a
silence of the timeout (no request of any client: a LabJack's timer is cleared
by any command-response, and by a write to its feed register) sets each output
whose action is on to its value.  Armed strict (its strict registers declared and
set), only a write of the key to the feed register clears the timer, as on a
T-series: other requests do not.  Like a LabJack, the settings cannot be written
while it is enabled (disable it first), and it fires again after each further
timeout of silence.  Out of the box it is off; `quadtank rig --watchdog S` starts
it armed with S s (a device whose watchdog a program armed and left on).
"""

from __future__ import annotations

from typing import Sequence

from quadtank_tui.daq.registers import Register, decode, encode
from quadtank_tui.daq.server import IllegalAddress
from quadtank_tui.daq.watchdog import Watchdog


class RigWatchdog:
    """The watchdog's registers and state in the rig (wall time is the rig's)."""

    def __init__(self, declared: Watchdog, stop_volts: dict[str, float], armed_for: float = 0.0) -> None:
        self.declared = declared
        self._words: dict[int, int] = {}
        self._set(declared.enable, 0.0)
        self._set(declared.timeout_register, 0.0)
        for a in declared.actions:
            self._set(a.value, 0.0)
            if a.enable is not None:
                self._set(a.enable, 0.0)
        if declared.feed is not None:
            self._set(declared.feed, 0.0)
        for reg in (declared.strict_enable, declared.strict_key):
            if reg is not None:
                self._set(reg, 0.0)
        if armed_for > 0:  # as a program left it: armed, each output to stop its pump
            for a in declared.actions:
                self._set(a.value, stop_volts[a.output])
                if a.enable is not None:
                    self._set(a.enable, 1.0)
            self._set(declared.timeout_register, armed_for)
            self._set(declared.enable, 1.0)
            # the register may round it (whole seconds): the rig keeps the S it was given
        self._power_up_timeout = armed_for

    def _set(self, reg: Register, value: float) -> None:
        self._words.update(zip(reg.span, encode(reg, value)))

    def _get(self, reg: Register) -> float:
        return decode(reg, [self._words[a] for a in reg.span])

    @property
    def enabled(self) -> bool:
        return self._get(self.declared.enable) != 0

    @property
    def timeout(self) -> float:
        """The timeout in force, s."""
        if self._power_up_timeout > 0:
            return self._power_up_timeout
        return self._get(self.declared.timeout_register)

    @property
    def strict(self) -> bool:
        """Armed strict: only the feed with the key clears the timer."""
        d = self.declared
        return d.strict and d.strict_enable is not None and self._get(d.strict_enable) != 0

    def clears(self, span: Sequence[int], values: Sequence[int]) -> bool:
        """Whether a write of `values` at `span` clears a strict watchdog's timer:
        the feed register written with the key set in its strict key register."""
        d = self.declared
        if d.feed is None or d.strict_key is None or not set(d.feed.span) <= set(span):
            return False
        words = dict(zip(span, values))
        return [words[a] for a in d.feed.span] == [self._words[a] for a in d.strict_key.span]

    def owns(self, address: int) -> bool:
        return address in self._words

    def words(self) -> dict[int, int]:
        return dict(self._words)

    def write(self, span: Sequence[int], values: Sequence[int]) -> None:
        """Store a write to its registers (the caller checked they are its own);
        IllegalAddress for a setting written while enabled, as a LabJack refuses it."""
        free = set(self.declared.enable.span) | set(self.declared.feed.span if self.declared.feed else ())
        if self.enabled and any(a not in free for a in span):
            raise IllegalAddress("the watchdog must be disabled before its settings are written")
        self._words.update(zip(span, values))
        if any(a in self.declared.timeout_register.span for a in span):
            self._power_up_timeout = 0.0  # a program set its own

    def actions(self) -> list[tuple[str, float]]:
        """(output, volts) of each output the watchdog sets on a timeout."""
        return [(a.output, self._get(a.value)) for a in self.declared.actions
                if a.enable is None or self._get(a.enable) != 0]

    def status(self) -> str:
        """For the rig's first line, e.g. "watchdog off" or "watchdog 1 s"."""
        return f"watchdog {self.timeout:g} s" if self.enabled else "watchdog off (a program arms it)"
