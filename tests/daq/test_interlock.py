"""The high-level interlock as pure logic (the loopback tests drive it through a rig)."""

from __future__ import annotations

from quadtank_tui.daq.interlock import Interlock


def test_an_overfull_tank_cuts_the_pump_that_feeds_it() -> None:
    lock = Interlock.for_height(0.95, 1.0)
    lock.update((0.50, 0.96, 0.20, 0.30))        # tank 2 over: pump 2 feeds it
    assert lock.cut((0.4, 0.6)) == (0.4, 0.0)
    assert lock.alarms(1.0) == ("interlock: tank 2 above 95 % of its height, pump 2 cut",)
    lock.update((0.50, 0.94, 0.20, 0.96))        # tank 4 over: pump 1 (1 - gamma1 goes up there)
    assert lock.cut((0.4, 0.6)) == (0.0, 0.0)    # tank 2 still inside the hysteresis band
    lock.update((0.50, 0.92, 0.20, 0.90))
    assert lock.cut((0.4, 0.6)) == (0.4, 0.6) and lock.alarms(1.0) == ()


def test_tank_three_cuts_pump_two_and_disabled_never_cuts() -> None:
    lock = Interlock.for_height(0.9, 2.0)
    lock.update((0.0, 0.0, 1.85, 0.0))
    assert lock.cut((1.0, 1.0)) == (1.0, 0.0)
    off = Interlock.for_height(0.9, 1.0, enabled=False)
    off.update((1.0, 1.0, 1.0, 1.0))
    assert off.cut((1.0, 1.0)) == (1.0, 1.0) and off.alarms(1.0) == ()
