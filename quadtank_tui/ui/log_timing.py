"""How long a log takes and when it ends (the Logging window).

A student choosing Points wants to know the experiment's length before LogOn,
and while logging, when to come back: the points take Points x Ts of process
time, which at a speed-up of x passes x times faster than the wall clock.
"""

from __future__ import annotations

import math
from datetime import datetime, timedelta

from quadtank_tui.engine.snapshot import Snapshot


def duration_text(seconds: float) -> str:
    """A duration as a person reads it: 45 s, 1 min 30 s, 2 h 5 min."""
    s = round(seconds)
    if s < 60:
        return f"{seconds:.3g} s" if seconds < 10 and seconds != s else f"{s} s"
    if s < 3600:
        minutes, rest = divmod(s, 60)
        return f"{minutes} min {rest} s" if rest else f"{minutes} min"
    hours, rest = divmod(s, 3600)
    minutes = round(rest / 60)
    return f"{hours} h {minutes} min" if minutes else f"{hours} h"


def _ends(process_seconds: float, snap: Snapshot, now: datetime) -> str:
    """When `process_seconds` of process time will have passed, at the speed in force."""
    speed = 1.0 if snap.realtime or snap.operation != "Simul" else snap.speed
    if math.isinf(speed):
        return "at once (speed max)"
    wall = process_seconds / speed
    at = f"x{speed:g}, " if speed != 1.0 else ""
    if snap.state != "Run":
        return f"{duration_text(wall)} after Run ({at}now paused)"
    end = (now + timedelta(seconds=wall)).strftime("%H:%M:%S")
    return f"at {end} ({at}in {duration_text(wall)})"


def log_timing(points: int | None, snap: Snapshot, now: datetime) -> str:
    """Two lines: what the Points in the field take at the Ts in force, and when
    the log ends (the running one, else one started now)."""
    ts = snap.params.tsamp
    log = snap.log
    if points is None or points < 1:
        first = ""
    else:
        first = f"{points} points x Ts {ts:g} s = {duration_text(points * ts)} of process time"
    if log.active:
        left = max(0, log.points - log.rows)
        second = f"This log ends {_ends(left * ts, snap, now)}"
    elif points is None or points < 1:
        second = ""
    else:
        second = f"LogOn now ends {_ends(points * ts, snap, now)}"
    return "\n".join(line for line in (first, second) if line)
