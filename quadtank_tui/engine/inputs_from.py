"""A script's `inputs_from: LOG` event: the pumps driven open loop by a log's inputs,
row by row, as `quadtank run --inputs-from LOG` does outside a script.

The event becomes events of the script: at its time the loop goes to Manual with
both references' waves off, and at the time of row k (the event's time plus k
sampling times) each reference's mean is set to that row's u1, u2, before the
sample, so the sample acts and logs exactly the logged inputs.  A simulator run
logged with the same `.par` and the same start comes back row for row.  The log's
sampling time must be the loop's when the event comes (set TSamp before it).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from quadtank_tui.files.log_reader import read_log
from quadtank_tui.files.script import Event

if TYPE_CHECKING:
    from quadtank_tui.engine.runner import Engine

#: The reference whose mean is each pump's signal in Manual.
MEANS = ("REFERENCE ONE.Mean", "REFERENCE TWO.Mean")
WAVES_OFF = {"REFERENCE ONE.On": 0, "REFERENCE TWO.On": 0}


def replay_events(engine: Engine, event: Event, script: str) -> list[Event]:
    """The events `event` (an inputs_from) stands for; ScriptError naming the script,
    the event and its line when the log cannot drive this loop."""
    path = str(event.value)
    try:
        log = read_log(path)
    except (OSError, ValueError) as exc:
        raise event.where(script, f"inputs_from {path}: {exc}") from None
    h = engine.snapshot().params.tsamp
    if log.tsamp is None or abs(log.tsamp - h) > 1e-9 * h:
        got = "no TSamp in its header" if log.tsamp is None else f"TSamp {log.tsamp:g} s"
        raise event.where(script, f"inputs_from {path}: {got}, the loop samples every {h:g} s "
                                  "(set SAMPLING TIME.TSamp before this event)")
    pumps = [k for k in ("u1", "u2") if k in log.variables]
    if not pumps or log.rows == 0:
        raise event.where(script, f"inputs_from {path}: no u1 or u2 column to drive the pumps with")
    columns = log.columns()
    out = [Event(event.at, "mode", "Manual", event.index, event.line),
           Event(event.at, "set", dict(WAVES_OFF), event.index, event.line)]
    for k in range(log.rows):
        values = {MEANS[int(p[1]) - 1]: float(columns[p][k]) for p in pumps}
        out.append(Event(event.at + k * h, "set", values, event.index, event.line))
    return out
