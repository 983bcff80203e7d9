"""The interlock's record over a run (engine/safety.py): per tank the samples held,
first and last, trips, and whether it still holds; the lines the summary prints."""

from __future__ import annotations

from quadtank_tui.engine.backend import InterlockHold
from quadtank_tui.engine.safety import InterlockRecord

T1 = InterlockHold(1, (1,), "interlock: tank 1 above 95 % of its height, pump 1 cut")
T3 = InterlockHold(3, (2,), "interlock: tank 3 above 95 % of its height, pump 2 cut")


def test_trips_releases_and_the_summary_lines() -> None:
    rec = InterlockRecord()
    assert rec.note(0.0, ()) == ([], []) and not rec.acted
    assert rec.note(0.1, (T1,)) == ([T1], [])
    assert rec.note(0.2, (T1, T3)) == ([T3], [])
    assert rec.note(0.3, (T3,)) == ([], [1])
    assert rec.note(0.4, (T1, T3)) == ([T1], [])
    assert rec.note(0.5, ()) == ([], [1, 3])
    assert rec.note(0.6, (T3,)) == ([T3], [])
    assert rec.acted
    assert rec.lines(0.1) == [
        "INTERLOCK  tank 1 above 95 % of its height: pump 1 held at 0 in 3 samples (0.3 s), t = 0.1 .. 0.4 s, 2 trips",
        "INTERLOCK  tank 3 above 95 % of its height: pump 2 held at 0 in 4 samples (0.4 s), t = 0.2 .. 0.6 s, "
        "2 trips; still holding at the end",
    ]
