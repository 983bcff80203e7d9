"""Main and Setup with the other rigs (issue 14): the process image draws the plant
in use, the analysis panel its figures and ICAD margins."""

from __future__ import annotations

import dataclasses

import pytest
from uikit import Recording, make_app

from textual.widgets import Input, Static

from quadtank_tui.core.parameters import PLANT_SETTINGS
from quadtank_tui.engine.commands import SetParams
from quadtank_tui.engine.loop import ControlLoop
from quadtank_tui.ui.screens.setup import operating_point_view
from quadtank_tui.ui.widgets.analysis_panel import AnalysisPanel, diagonal_pi, plant_lines
from quadtank_tui.ui.widgets.process_image import draw


def snapshot_of(name: str, **changes):
    return dataclasses.replace(ControlLoop(PLANT_SETTINGS[name]).publish(), **changes)


@pytest.mark.parametrize("name, tanks, pumps", [
    ("coupled-cascade", 2, 1), ("coupled-tito", 2, 2), ("desautel-qtp", 4, 2)])
def test_the_image_draws_the_plant_in_use(name: str, tanks: int, pumps: int) -> None:
    text, boxes = draw(snapshot_of(name, state="Run", u=(0.3, 0.2)), 60, 20)
    actions = [b.action for b in boxes]
    assert actions == [f"tank({i})" for i in sorted(range(1, tanks + 1), key=lambda i: actions.index(
        f"tank({i})"))] + [f"pump({i})" for i in range(1, pumps + 1)]
    plain = text.plain
    assert ("P2" in plain) == (pumps == 2)
    for i in range(1, tanks + 1):
        assert f"{i}:" in plain


def test_cascade_reads_its_levels() -> None:
    text, _ = draw(snapshot_of("coupled-cascade"), 40, 14)
    assert "1:0.28" in text.plain and "2:0.27" in text.plain  # 15 cm / 5.431 cm/V / 10 V


def test_orifice_arrow_follows_the_water() -> None:
    forward, _ = draw(snapshot_of("coupled-tito", state="Run", y=(0.5, 0.3, 0.0, 0.0)), 60, 20)
    back, _ = draw(snapshot_of("coupled-tito", state="Run", y=(0.3, 0.5, 0.0, 0.0)), 60, 20)
    assert "▶" in forward.plain and "◀" not in forward.plain
    assert "◀" in back.plain and "▶" not in back.plain


def test_setup_view_puts_the_pumps_at_the_holding_inputs() -> None:
    view = operating_point_view(snapshot_of("coupled-cascade"))
    assert view.u[0] == pytest.approx(6.769218 / 22, abs=1e-6)
    assert view.y[:2] == pytest.approx((15 / 5.4310 / 10, 14.727394 / 5.5558 / 10), abs=1e-6)


def test_analysis_panel_lines_with_icad_margins() -> None:
    p = PLANT_SETTINGS["coupled-tito"]
    assert p.process is not None
    drawn = plant_lines(p.process, *diagonal_pi(p))
    assert isinstance(drawn, list), drawn  # the lines, not a reason there are none
    lines = [t.plain for t in drawn]
    assert lines[-3:] == ["C1 ωc 0.782 rad/s  PM 80°", "C2 ωc 0.157 rad/s  PM 76°", "ICAD γ(0) 0.52  stable"]
    q = PLANT_SETTINGS["desautel-qtp"]
    assert q.process is not None
    drawn = plant_lines(q.process, *diagonal_pi(q))
    assert isinstance(drawn, list), drawn
    assert [t.plain for t in drawn][1] == "Zeros   -0.0609  -0.0242"


@pytest.mark.parametrize("name", ["coupled-cascade", "coupled-tito"])
def test_main_with_another_plant_80x24(snap_compare, make_engine, name: str) -> None:
    engine: Recording = make_engine(PLANT_SETTINGS[name])
    assert snap_compare(make_app(engine), terminal_size=(80, 24))


def test_setup_with_the_two_input_rig(snap_compare, make_engine) -> None:
    engine: Recording = make_engine(PLANT_SETTINGS["coupled-tito"])
    assert snap_compare(make_app(engine), terminal_size=(120, 40), press=["S"])


async def test_fault_window_switches_a_fault_on_and_off(engine: Recording) -> None:
    from quadtank_tui.engine import commands as c
    from quadtank_tui.ui.windows.faults import FaultWindow

    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("F")
        assert isinstance(app.screen, FaultWindow)
        await pilot.press("enter")                      # leak (the first kind) chosen: to Target
        await pilot.press("tab", *"0.02", "enter")      # value, On
        await pilot.pause()
        assert engine.sent(c.SetFault) == [c.SetFault("leak", 1, 0.02, True)]
        engine.run_for(0.2)
        assert engine.snapshot().faults == "leak tank 1 (0.02)"
        await pilot.press("F")
        await pilot.press("enter")
        await pilot.click("#off")
        await pilot.pause()
        assert engine.sent(c.SetFault)[-1] == c.SetFault("leak", 1, 0.0, False)
        engine.run_for(0.2)
        assert engine.snapshot().faults == ""


def test_fault_window_80x24(snap_compare, engine: Recording) -> None:
    assert snap_compare(make_app(engine), terminal_size=(80, 24), press=["F"])


async def test_another_plants_table_opens_its_plant_window(make_engine) -> None:
    """Enter on the process table (any row) opens the plant window, not a tank's."""
    from quadtank_tui.ui.windows.plant_setup import PlantSetupWindow

    engine: Recording = make_engine(PLANT_SETTINGS["coupled-tito"])
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("S")
        await pilot.pause()
        await pilot.press("h", "down", "enter")
        await pilot.pause()
        assert isinstance(app.screen, PlantSetupWindow)
        assert [k for k, _, _ in app.screen.rows][:4] == ["Level1", "Level2", "A1", "A2"]
        await pilot.press("escape")
        await pilot.pause()
        assert engine.sent(SetParams) == []


async def open_plant_window(pilot, key: str):
    """Setup, the process table, Enter: the plant window with the focus in `key`'s field."""
    from quadtank_tui.ui.windows.plant_setup import PlantSetupWindow

    await pilot.press("S")
    await pilot.pause()
    await pilot.press("h", "enter")
    await pilot.pause()
    window = pilot.app.screen
    assert isinstance(window, PlantSetupWindow)
    window.query_one(f"#f-{[k for k, _, _ in window.rows].index(key)}", Input).focus()
    await pilot.pause()
    return window


async def test_typing_a_plant_value_sets_it_between_samples(make_engine) -> None:
    """Desautel's CTP: alpha1 typed as 0.0105; x2 follows at once in the window,
    (alpha1 / alpha2)^2 x1 = 16.9379 cm (2.1.6), and Set sends the one value; the
    running simulation takes the new orifice at the next sample."""
    from quadtank_tui.ui.screens.setup import SetupScreen

    engine: Recording = make_engine(PLANT_SETTINGS["coupled-cascade"])
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        window = await open_plant_window(pilot, "alpha1")
        await pilot.press(*"0.0105")
        await pilot.pause()
        assert window.query_one("#f-1", Input).value == "16.9379"
        assert window.query_one("#row-2").has_class("-modified")
        assert engine.sent(SetParams) == []  # nothing before Set
        await pilot.press("enter")
        await pilot.pause()
        assert isinstance(app.screen, SetupScreen)
        assert engine.sent(SetParams) == [SetParams({"PLANT.alpha1": 0.0105})]
        engine.run_for(0.2)
        assert engine.loop.sim.plant.values()["alpha1"] == 0.0105
        assert engine.snapshot().params.process.levels == pytest.approx((15.0, 15 * (0.0105 / 0.0098811) ** 2))


async def test_process_default_puts_the_published_plant_back(make_engine) -> None:
    engine: Recording = make_engine(PLANT_SETTINGS["coupled-cascade"])
    assert engine.submit(SetParams({"PLANT.alpha1": 0.0105, "PLANT.Level1": 12.0})).result().ok
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("S")
        await pilot.pause()
        await pilot.press("d")
        await pilot.pause()
        engine.run_for(0.2)
        assert engine.snapshot().params.process == PLANT_SETTINGS["coupled-cascade"].process


async def test_a_refused_plant_value_changes_nothing_and_says_why(make_engine) -> None:
    engine: Recording = make_engine(PLANT_SETTINGS["coupled-tito"])
    before = engine.snapshot().params
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        window = await open_plant_window(pilot, "H3")
        h3 = [k for k, _, _ in window.rows].index("H3")
        await pilot.press(*"0.5", "enter")  # the drain above the brim (0.3 m)
        await pilot.pause()
        assert app.screen is window
        assert str(window.query_one(f"#e-{h3}", Static).render()) == "H3 must be in [0, hmax), got 0.5"
        assert "refused" in str(window.query_one(AnalysisPanel).render())
        await pilot.click("#default")  # the published values back
        await pilot.pause()
        assert window.query_one(f"#f-{h3}", Input).value == "0.03"
        await pilot.press("escape")
        await pilot.pause()
        assert engine.sent(SetParams) == [] and engine.snapshot().params == before


@pytest.mark.parametrize("name", ["coupled-cascade", "desautel-qtp"])
def test_setup_with_another_plant_120x40(snap_compare, make_engine, name: str) -> None:
    engine: Recording = make_engine(PLANT_SETTINGS[name])
    assert snap_compare(make_app(engine), terminal_size=(120, 40), press=["S"])


def test_main_with_desautels_quadruple_tank_80x24(snap_compare, make_engine) -> None:
    engine: Recording = make_engine(PLANT_SETTINGS["desautel-qtp"])
    assert snap_compare(make_app(engine), terminal_size=(80, 24))


def test_plant_window_80x24(snap_compare, make_engine) -> None:
    engine: Recording = make_engine(PLANT_SETTINGS["coupled-tito"])
    assert snap_compare(make_app(engine), terminal_size=(80, 24), press=["S", "h", "enter"])
