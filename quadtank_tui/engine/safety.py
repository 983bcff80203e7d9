"""What the rig's interlock did during a run, for its summary.

The interlock (daq/interlock.py) holds the pumps feeding an overfull tank at 0
whatever the controller asks; a headless run on a rig used to end with status 0
and not a word about it, so a lab's script could not tell an experiment the
interlock held at 0 from one that ran.  The loop notes every write here
(`InterlockRecord.note`): per tank, the samples its trip held which pumps, the
first and last of them (process time), how many separate trips, and whether it
still held at the end.  Pure bookkeeping, no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from quadtank_tui.engine.backend import InterlockHold


@dataclass
class TankHolds:
    """One tank's interlock over a run."""

    tank: int
    pumps: tuple[int, ...]     # 1-based, as the alarm names them
    alarm: str                 # the last alarm line (its limit in % of the height)
    samples: int               # samples at which the trip held the pumps at 0
    first: float               # process time of the first of them, s
    last: float                # ... and of the last
    trips: int = 1             # separate trips (released in between)
    holding: bool = True       # tripped at the last write


class InterlockRecord:
    """The interlock's holds over a run, tank by tank."""

    def __init__(self) -> None:
        self._tanks: dict[int, TankHolds] = {}

    @property
    def acted(self) -> bool:
        """Whether the interlock held a pump at 0 at any sample of the run."""
        return bool(self._tanks)

    @property
    def tanks(self) -> tuple[TankHolds, ...]:
        return tuple(self._tanks[k] for k in sorted(self._tanks))

    def note(self, t: float, holds: Sequence[InterlockHold]) -> tuple[list[InterlockHold], list[int]]:
        """The holds at the write of the sample at process time `t`; returns the
        trips that began here and the tanks released since the last write (for the
        log's `%` lines)."""
        if not holds and not self._tanks:  # the every-sample case: nothing to note
            return [], []
        began: list[InterlockHold] = []
        now = {h.tank for h in holds}
        for h in holds:
            rec = self._tanks.get(h.tank)
            if rec is None:
                self._tanks[h.tank] = TankHolds(h.tank, h.pumps, h.alarm, 1, t, t)
                began.append(h)
                continue
            if not rec.holding:
                rec.trips += 1
                began.append(h)
            rec.pumps, rec.alarm, rec.holding = h.pumps, h.alarm, True
            rec.samples += 1
            rec.last = t
        released = [rec.tank for rec in self._tanks.values() if rec.holding and rec.tank not in now]
        for tank in released:
            self._tanks[tank].holding = False
        return began, released

    def lines(self, tsamp: float) -> list[str]:
        """One summary line per tank the interlock held, e.g. "INTERLOCK  tank 4
        above 95 % of its height: pump 1 held at 0 in 153 samples (15.3 s), t = 42.1
        .. 57.3 s, 2 trips; still holding at the end"."""
        out = []
        for rec in self.tanks:
            what = rec.alarm.removeprefix("interlock: ").rsplit(", ", 1)[0]
            pumps = ("pump " if len(rec.pumps) == 1 else "pumps ") + ", ".join(map(str, rec.pumps))
            trips = "1 trip" if rec.trips == 1 else f"{rec.trips} trips"
            end = "; still holding at the end" if rec.holding else ""
            out.append(f"INTERLOCK  {what}: {pumps} held at 0 in {rec.samples} samples "
                       f"({rec.samples * tsamp:g} s), t = {rec.first:g} .. {rec.last:g} s, {trips}{end}")
        return out
