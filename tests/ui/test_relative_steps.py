"""A signed value in the input signal window steps the mean or the amplitude from
the value in force (issue 17: "+0.1" as the thesis's step experiments say it)."""

from __future__ import annotations

from textual.widgets import Input, Static

from bursts import burst
from uikit import Recording, make_app

from quadtank_tui.engine import commands as c
from quadtank_tui.ui.windows.signals import InputSignalWindow

MEAN, AMPLITUDE = "REFERENCE ONE.Mean", "REFERENCE ONE.Amplitude"


async def test_plus_steps_the_mean_up_from_the_value_in_force(engine: Recording) -> None:
    assert engine.snapshot().params.get(MEAN) == 0.3
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await burst(pilot, "i", *"+0.1", "enter")
        assert app.screen is app.main
    assert engine.sent(c.SetParams) == [c.SetParams({MEAN: 0.4})]
    assert engine.snapshot().params.get(MEAN) == 0.4


async def test_minus_steps_the_amplitude_down_and_the_reference_in_automatic(engine: Recording) -> None:
    engine.submit(c.SetControlMode("Automatic"))
    before = engine.snapshot().params.get(MEAN)
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await burst(pilot, "i", *"-0.05", "tab", *"-0.05", "enter")
        assert app.screen is app.main
    p = engine.snapshot().params
    assert p.get(MEAN) == round(before - 0.05, 9)
    assert p.get(AMPLITUDE) == 0.0   # 0.05 - 0.05


async def test_a_refused_step_says_from_what_and_changes_nothing(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await burst(pilot, "i", "tab", *"+0.99", "enter")
        assert isinstance(app.screen, InputSignalWindow), "a refused value keeps the window open"
        assert str(app.screen.query_one("#e-1", Static).render()) == \
            "0.05 + 0.99 = 1.04: must be <= 1, got 1.04"
        assert app.screen.query_one("#f-1", Input).value == "+0.99"
        await burst(pilot, "escape")
    assert engine.sent(c.SetParams) == []
    assert engine.snapshot().params.get(AMPLITUDE) == 0.05


async def test_an_unsigned_value_is_still_the_value(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await burst(pilot, "i", *"0.1", "enter")
    assert engine.snapshot().params.get(MEAN) == 0.1
