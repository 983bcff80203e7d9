"""The high-level interlock: cut the pump that feeds an overfull tank, and say so.

Pump 1 feeds tanks 1 and 4 through valve 1, pump 2 feeds tanks 2 and 3 through
valve 2 (Johansson's process; plant.py), so a tank above the limit cuts its own
pump whatever the controller asks.  The trip holds until the level is back below
the limit minus a hysteresis, so a level sitting on the limit does not make the
pump chatter.  Pure logic: the DAQ backend feeds it each sample's levels.

Another plant gives its own `feeders` (config.PlantChannels, from the plant's
drawing): the pumps pouring into each tank, or, for a tank no pump pours into (the
lower tank of the cascade), the pumps upstream of it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

from quadtank_tui.engine.backend import InterlockHold

#: Which pump (0-based) feeds each tank 1..4 of the quadruple tank.
FEEDER = (0, 1, 1, 0)
#: The same as the pumps (0-based) each tank's trip cuts.
QUADTANK_FEEDERS: tuple[tuple[int, ...], ...] = tuple((f,) for f in FEEDER)
#: The trip releases this far (fraction of the tank height) below the limit.
HYSTERESIS = 0.02


@dataclass
class Interlock:
    """Level limit per tank, in the same units as the levels it is given.

    `limit` is the trip level (e.g. 0.95 of the height in normalized units);
    `release` the level below which a tripped tank lets its pump run again.
    """

    limit: float
    release: float
    enabled: bool = True
    tripped: set[int] = field(default_factory=set)
    #: per tank, the pumps (0-based) a trip cuts
    feeders: tuple[tuple[int, ...], ...] = QUADTANK_FEEDERS

    @classmethod
    def for_height(cls, fraction: float, full_scale: float, *, enabled: bool = True,
                   feeders: tuple[tuple[int, ...], ...] = QUADTANK_FEEDERS) -> Interlock:
        """Trip at `fraction` of `full_scale` (the tank height in the levels' units)."""
        return cls(limit=fraction * full_scale, release=(fraction - HYSTERESIS) * full_scale, enabled=enabled,
                   feeders=feeders)

    def update(self, levels: Sequence[float]) -> None:
        """Trip tanks above the limit; release those back below `release`."""
        if not self.enabled:
            self.tripped.clear()
            return
        for i, y in enumerate(levels[:len(self.feeders)]):
            if y >= self.limit:
                self.tripped.add(i)
            elif y < self.release:
                self.tripped.discard(i)

    def cut(self, u: tuple[float, float]) -> tuple[float, float]:
        """`u` with the pumps feeding a tripped tank set to 0."""
        cut = {pump for i in self.tripped for pump in self.feeders[i]}
        return (0.0 if 0 in cut else u[0], 0.0 if 1 in cut else u[1])

    def alarms(self, full_scale: float) -> tuple[str, ...]:
        """One line per tripped tank, e.g. "interlock: tank 1 above 95 % of its height, pump 1 cut"."""
        return tuple(hold.alarm for hold in self.holds(full_scale))

    def holds(self, full_scale: float) -> tuple[InterlockHold, ...]:
        """Per tripped tank, the pumps its trip cuts (1-based) and its alarm line."""
        pct = 100.0 * self.limit / full_scale
        return tuple(
            InterlockHold(i + 1, tuple(p + 1 for p in self.feeders[i]),
                          f"interlock: tank {i + 1} above {pct:.0f} % of its height, {_pumps(self.feeders[i])} cut")
            for i in sorted(self.tripped)
        )


def _pumps(pumps: tuple[int, ...]) -> str:
    """"pump 1", "pumps 1, 2"."""
    return ("pump " if len(pumps) == 1 else "pumps ") + ", ".join(str(p + 1) for p in pumps)
