"""The `+` and `-` keys in a burst (issue 28): over SSH ten presses arrive
together, before the engine has applied the first SetSpeed; each press must step
from the one before, as when typed half a second apart."""

from __future__ import annotations

from concurrent.futures import Future
from typing import Any

from bursts import burst
from uikit import Recording, make_app

from quadtank_tui.engine import commands as c
from quadtank_tui.ui.asked_speed import AskedSpeed


class Lagging:
    """The engine as seen from a client while its loop is busy: commands are
    queued, their answers and the snapshot they change come later (`catch_up`)."""

    def __init__(self, engine: Recording) -> None:
        self.engine = engine
        self.held: list[tuple[c.Command, Future[Any]]] = []

    def submit(self, command: c.Command) -> Future[Any]:
        if not isinstance(command, c.SetSpeed):
            return self.engine.submit(command)
        future: Future[Any] = Future()
        self.held.append((command, future))
        return future

    def catch_up(self) -> None:
        for command, future in self.held:
            future.set_result(self.engine.submit(command).result())
        self.held.clear()

    def __getattr__(self, name: str) -> Any:
        return getattr(self.engine, name)


async def test_ten_plus_arriving_together_give_x1000(make_engine: Any) -> None:
    engine = Lagging(make_engine(clock="virtual", speed=1.0))
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await burst(pilot, *["plus"] * 10)
        engine.catch_up()
        await pilot.pause()
        assert engine.snapshot().speed == 1000.0
    assert [cmd.factor for cmd in engine.sent(c.SetSpeed)] == [2, 5, 10, 20, 50, 100, 200, 500, 1000]


async def test_a_burst_of_mixed_keys_acts_in_order(make_engine: Any) -> None:
    engine = Lagging(make_engine(clock="virtual", speed=1.0))
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await burst(pilot, "plus", "plus", "plus", "minus", "plus", "plus", "minus", "minus", "minus")
        engine.catch_up()
        await pilot.pause()
        # then, the engine caught up, the same keys a while apart step from x5
        await burst(pilot, "plus")
        engine.catch_up()
        await pilot.pause()
    assert [cmd.factor for cmd in engine.sent(c.SetSpeed)] == [2, 5, 10, 5, 10, 20, 10, 5, 2, 5]


def test_a_refused_request_leaves_the_snapshot_in_charge() -> None:
    asked = AskedSpeed(clock=lambda: 0.0)
    asked.asked(2.0)
    assert asked.base(1.0) == 2.0  # on its way
    asked.answered(False)
    assert asked.base(1.0) == 1.0
    asked.asked(5.0)
    asked.answered(True)
    assert asked.base(2.0) == 5.0  # answered, the snapshot not there yet
    assert asked.base(5.0) == 5.0
    assert asked.base(20.0) == 20.0  # forgotten once seen: another client's speed wins
