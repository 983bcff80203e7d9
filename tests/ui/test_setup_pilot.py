"""The Setup screen driven by keys (S1-S6): what a user does and what reaches the
engine."""

from __future__ import annotations

from pathlib import Path

import pytest
from textual.widgets import Input, Static

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.engine.commands import SetParams
from quadtank_tui.ui.screens.setup import SetupScreen
from quadtank_tui.ui.widgets.analysis_panel import AnalysisPanel, analysis_of
from quadtank_tui.ui.windows.par_files import ParFileWindow
from quadtank_tui.ui.windows.tank_setup import TankSetupWindow
from quadtank_tui.ui.windows.wave import WaveWindow

from bursts import pause_until  # noqa: E402
from uikit import open_setup  # noqa: E402


@pytest.fixture
def app(setup_app):
    """Main as the CLI builds it; each test goes to Setup by its key."""
    return setup_app


async def _type(pilot, text: str) -> None:
    await pilot.press(*text)


async def _set_tank(pilot, tank: int, field: str, value: str) -> None:
    """Open tank `tank` from the process table by keys, type `value` into `field`, Set."""
    app = pilot.app
    await pilot.press("h", *(["up"] * 3), *(["down"] * (tank - 1)), "enter")
    window = app.screen
    assert isinstance(window, TankSetupWindow) and window.tank == tank
    window.query_one(f"#f-{field}", Input).focus()
    await pilot.pause()
    await _type(pilot, value)
    await pilot.press("enter")
    await pilot.pause()
    assert isinstance(app.screen, SetupScreen)


def _zeros(app) -> list[float]:
    a = analysis_of(app.engine.snapshot().params.simulation)
    assert not isinstance(a, str), a  # an analysis, not the reason there is none
    return [round(z.real, 4) for z in a.zeros]


def _panel_text(app) -> str:
    return str(app.screen.query_one("#analysis", AnalysisPanel).render())


async def test_moving_the_valves_across_one_moves_a_zero_into_the_rhp(app) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        assert _zeros(app) == [-0.058, -0.0172]
        assert "minimum phase" in _panel_text(app) and "nonminimum" not in _panel_text(app)
        # gamma1 + gamma2 from 1.30 to 0.77 (P+'s valves), typed in the tank windows.
        await _set_tank(pilot, 1, "Valve", "0.43")
        await _set_tank(pilot, 2, "Valve", "0.34")
        assert app.engine.snapshot().params.simulation.valves == (0.43, 0.34)
        # At P-'s levels the zeros are -0.0977 and +0.0225: one crossed into the RHP.
        assert _zeros(app) == [-0.0977, 0.0225]
        text = _panel_text(app)
        assert "nonminimum phase" in text and "+0.0225 (RHP)" in text and "0.77 < 1" in text
        # With P+'s upper levels too (the outlets held, so T3, T4 become P+'s 39.0 and
        # 56.1 s), the zeros are P+'s: -0.0562 and +0.0128 (paper: -0.057, +0.013).
        await _set_tank(pilot, 3, "OpPoint", "0.24")
        await _set_tank(pilot, 4, "OpPoint", "0.245")
        assert _zeros(app) == [-0.0562, 0.0128]
        assert "-0.0562  +0.0128 (RHP)" in _panel_text(app)


async def test_tank_window_links_the_values_and_sets_them_together(app) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        await pilot.press("h", "enter")
        window = app.screen
        assert isinstance(window, TankSetupWindow)
        window.query_one("#f-Diameter", Input).focus()
        await pilot.pause()
        await _type(pilot, "6.5")
        await pilot.pause()
        # The time constant follows at once (the outlet held); nothing is set yet.
        # T = T0 (d / d0)^2 = 62.70339 (6.5 / 5.970821)^2, exactly: the outlet is held.
        t_expected = PRESET.simulation.time_constants[0] * (6.5 / PRESET.simulation.diameters[0]) ** 2
        assert float(window.query_one("#f-TimeConst", Input).value) == pytest.approx(t_expected, abs=1e-4)  # shown to 6 digits
        assert "held fixed" in str(window.query_one("#outlet").render())
        assert app.engine.snapshot().params == PRESET
        await pilot.press("enter")
        await pilot.pause()
        sim = app.engine.snapshot().params.simulation
        assert sim.diameters[0] == 6.5 and sim.time_constants[0] == pytest.approx(t_expected, rel=1e-12)
        assert app.engine.snapshot().params.quadtank_constants().a1 == pytest.approx(PRESET.quadtank_constants().a1, rel=1e-7)


async def test_tank_window_refuses_a_bad_value_and_default_restores(app) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        await app.screen.run_action("tank(1)")
        await pilot.pause()
        window = app.screen
        window.query_one("#f-Valve", Input).focus()
        await pilot.pause()
        await _type(pilot, "1.3")
        await pilot.press("enter")
        await pilot.pause()
        assert app.screen is window  # still open, the reason next to the field
        assert "must be <= 1" in str(window.query_one("#e-Valve", Static).render())
        window.query_one("#f-TimeConst", Input).value = "80"
        await pilot.pause()
        assert window.query_one("#row-TimeConst").has_class("-modified")
        await pilot.click("#default")  # (ctrl+d is the Input's delete-right while a field has the focus)
        await pilot.pause()
        assert window.query_one("#f-TimeConst", Input).value == "62.7034"  # PRESET: 62.70339
        assert not window.query_one("#row-TimeConst").has_class("-modified")
        await pilot.press("escape")
        await pilot.pause()
        assert app.engine.snapshot().params == PRESET


async def test_wave_window_refuses_a_too_short_period_with_the_shortest_allowed(app) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        await pilot.press("i")
        window = app.screen
        assert isinstance(window, WaveWindow)
        window.query_one("#f-2", Input).focus()
        window.query_one("#f-2", Input).value = "0.1"  # Period
        await pilot.press("ctrl+t")  # Square -> Sine, from inside a field
        await pilot.pause()
        await window.run_action("set")
        await pilot.pause()
        assert app.screen is window
        assert "the shortest allowed is 0.2 s" in str(window.query_one("#e-2", Static).render())
        # PRBS: the period is in samples; 3 samples and a seed are fine.
        await pilot.press("ctrl+t")
        window.query_one("#f-2", Input).value = "3"
        window.query_one("#f-3", Input).value = "7"
        await pilot.pause()
        await window.run_action("set")
        await pilot.pause()
        ref = app.engine.snapshot().params.references[0]
        assert (ref.wave.value, ref.period, ref.seed) == ("PRBS", 3.0, 7)
        assert app.engine.snapshot().params.references[1] == PRESET.references[1]


async def test_sampling_time_is_validated(app) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        await pilot.press("s")
        await _type(pilot, "20")
        await pilot.press("enter")
        await pilot.pause()
        assert "must be >= 50" in str(app.screen.query_one("#e-0", Static).render())
        await pilot.press("ctrl+a", "ctrl+k")
        await _type(pilot, "250")
        await pilot.press("enter")
        await pilot.pause()
        assert isinstance(app.screen, SetupScreen)
        assert app.engine.snapshot().params.tsamp_ms == 250.0


async def test_pid_extras_are_set_from_setup(app) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        await pilot.press("1")
        await pilot.pause()
        window = app.screen
        window.query_one("#f-8", Input).value = "0.5"  # b
        window.query_one("#f-5", Input).value = "20"  # N
        await pilot.pause()
        assert window.query_one("#row-8").has_class("-modified")
        await window.run_action("set")
        await pilot.pause()
        pid = app.engine.snapshot().params.controllers[0].pid
        assert (pid.b, pid.N, pid.K) == (0.5, 20.0, 3.0)
        await pilot.press("1")
        await pilot.pause()
        app.screen.query_one("#f-7", Input).value = "1.5"  # a out of [0, 1]
        await pilot.pause()
        await app.screen.run_action("set")
        await pilot.pause()
        assert "must be <= 1" in str(app.screen.query_one("#e-7", Static).render())


# --- parameter files (S5) -----------------------------------------------------------------

def _change(app, values: dict[str, float | str]) -> None:
    """Values changed elsewhere (Main, another window): the tank windows are tested above."""
    assert app.engine.submit(SetParams(values)).result().ok

async def _par(pilot, name: str, action: str) -> None:
    await pilot.press("f")
    window = pilot.app.screen
    assert isinstance(window, ParFileWindow)
    await pilot.press(*name)  # typed, as a user does
    await pilot.press(action)
    await pilot.pause()


async def test_save_change_load_restores(app) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        await _set_tank(pilot, 1, "Valve", "0.43")
        saved = app.engine.snapshot().params
        await _par(pilot, "mysetting", "ctrl+s")
        assert Path("params/mysetting.par").exists()
        _change(app, {"SIMULATION.Valve1": 0.9, "SIMULATION.Diameter3": 7.0, "SAMPLING TIME.TSamp": 200.0})
        assert app.engine.snapshot().params != saved
        await _par(pilot, "mysetting", "ctrl+l")
        assert isinstance(app.screen, SetupScreen)
        assert app.engine.snapshot().params == saved
        # Saving again under the same name asks first; "n" keeps the file.
        before = Path("params/mysetting.par").read_text()
        _change(app, {"SIMULATION.Valve1": 0.5})
        await _par(pilot, "mysetting", "ctrl+s")
        assert app.screen.__class__.__name__ == "ConfirmWindow"
        await pilot.press("n")
        await pilot.pause()
        assert "kept as it was" in str(app.screen.query_one("#par-error", Static).render())
        assert Path("params/mysetting.par").read_text() == before


@pytest.fixture
def lab_user(monkeypatch: pytest.MonkeyPatch, tmp_path: Path):
    """Be `user` (uid 50001 alice, a teacher; 50002 bob, a student) to the lab's
    role checks, with a lab file naming the group `teachers`."""
    from quadtank_tui.session import roles

    lab = tmp_path / "lab.yaml"
    lab.write_text("admin_group: teachers\n")
    monkeypatch.setenv("QUADTANK_LAB", str(lab))
    monkeypatch.setattr(roles, "group_id", {"teachers": 60001}.get)
    monkeypatch.setattr(roles, "groups_of", lambda uid: {60001} if uid == 50001 else {60002})
    monkeypatch.setattr(roles, "user_name", {50001: "alice", 50002: "bob"}.get)

    def be(user: str) -> None:
        uid = {"alice": 50001, "bob": 50002}[user]
        monkeypatch.setattr(roles, "current_user", lambda: roles.Peer(uid, 60002, 4242, user))
    return be


async def test_saving_as_default_is_refused(app, lab_user) -> None:
    lab_user("bob")  # a student
    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        before = Path("params/default.par").read_bytes()
        _change(app, {"SIMULATION.Valve2": 0.34})
        for name, why in (("default", "Not saved: saving default.par needs an administrator (member of group "
                           "teachers); you are bob."),
                          ("Default.par", "needs an administrator"),
                          ("preset", "Not saved: 'preset' is reserved")):
            await _par(pilot, name, "ctrl+s")
            window = app.screen
            assert isinstance(window, ParFileWindow)
            assert why in str(window.query_one("#par-error", Static).render())
            await pilot.press("escape")
            await pilot.pause()
        assert Path("params/default.par").read_bytes() == before
        assert not Path("params/preset.par").exists()


async def test_an_administrator_saves_default_par_after_asking(app, lab_user) -> None:
    from quadtank_tui.files.par import read_par

    lab_user("alice")  # a teacher
    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        before = Path("params/default.par").read_bytes()
        _change(app, {"SIMULATION.Valve2": 0.34})
        await _par(pilot, "default", "ctrl+s")
        assert app.screen.__class__.__name__ == "ConfirmWindow"
        await pilot.press("n")  # not this time
        await pilot.pause()
        assert "default.par is kept as it was" in str(app.screen.query_one("#par-error", Static).render())
        assert Path("params/default.par").read_bytes() == before
        await pilot.press("ctrl+s", "y")
        await pilot.pause()
        await pause_until(pilot, lambda: Path("params/default.par").read_bytes() != before,
                          what="the loop to write default.par")
        assert isinstance(app.screen, SetupScreen)
        assert read_par("params/default.par").params.simulation.valves == (0.7, 0.34)


async def test_loading_a_broken_file_names_file_line_key_and_changes_nothing(app) -> None:
    Path("params/broken.par").write_text(
        "% TANK PAR-file\n\nSAMPLING TIME\nTSamp 100.0000\n\nSIMULATION\nValve1 0.5\nValve2 1.7\n"
    )
    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        _change(app, {"SIMULATION.Valve1": 0.43})
        before = app.engine.snapshot().params
        await _par(pilot, "broken", "enter")
        window = app.screen
        assert isinstance(window, ParFileWindow)  # opened again, saying why
        text = str(window.query_one("#par-error", Static).render())
        assert "params/broken.par, line 8: SIMULATION.Valve2: must be <= 1, got 1.7" in text
        assert "unchanged" in text
        assert app.engine.snapshot().params == before


async def test_default_all_reloads_default_par_after_asking(app) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        _change(app, {"SIMULATION.Valve2": 0.34})
        await pilot.press("D")
        await pilot.press("n")
        await pilot.pause()
        assert app.engine.snapshot().params.simulation.valves == (0.7, 0.34)
        await pilot.press("D", "y")
        await pilot.pause()
        assert app.engine.snapshot().params == app.engine.defaults()
        _change(app, {"SIMULATION.Diameter3": 8.0})
        await pilot.press("d")  # process default: the SIMULATION section only
        await pilot.pause()
        assert app.engine.snapshot().params.simulation == app.engine.defaults().simulation


async def test_a_click_on_a_tank_of_the_image_opens_its_window(app) -> None:
    from quadtank_tui.ui.widgets.process_image import ProcessImage

    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        image = app.screen.query_one(ProcessImage)
        box = next(b for b in image._boxes if b.action == "tank(3)")
        # The image has a one-cell border: content cell (x, y) is at (x + 1, y + 1).
        await pilot.click(ProcessImage, offset=(box.x0 + 2, box.y0 + 2))
        await pilot.pause()
        window = app.screen
        assert isinstance(window, TankSetupWindow) and window.tank == 3
        assert [k.split(".")[1] for k in window.keys] == ["OpPoint3", "Diameter3", "TimeConst3"]  # no valve


async def test_a_click_on_the_sampling_time_opens_its_window(app) -> None:
    from quadtank_tui.ui.windows.sampling import SamplingTimeWindow

    async with app.run_test(size=(80, 24)) as pilot:
        await open_setup(pilot)
        await pilot.click("#sampling")
        await pilot.pause()
        assert isinstance(app.screen, SamplingTimeWindow)


async def test_the_controller_table_follows_the_family(app) -> None:
    from quadtank_tui.ui.widgets.setup_tables import ControllerTable

    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        table = app.screen.query_one(ControllerTable)
        headers = lambda: [str(c.label) for c in table.columns.values()][1:]  # noqa: E731
        assert headers()[:3] == ["K", "Ti", "Td"] and "N" in headers() and "b" in headers()
        _change(app, {"CONTROL.Type": "General"})
        app.screen.refresh_view()  # what the screen's refresh timer does; no race with it
        await pilot.pause()
        assert headers() == ["Degree", "s0", "s1", "s2", "s3", "s4", "r1", "r2", "r3", "r4"]
        assert "General" in str(table.border_title)


async def test_setup_opens_main_s_windows_and_s_goes_back(app) -> None:
    from quadtank_tui.ui.screens.main import MainScreen
    from quadtank_tui.ui.windows.controller_windows import ControllerTypeWindow, GeneralWindow

    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        await pilot.press("t")
        assert isinstance(app.screen, ControllerTypeWindow)
        await pilot.press("escape")
        _change(app, {"CONTROL.Type": "General"})
        await pilot.press("1")
        assert isinstance(app.screen, GeneralWindow)  # a General element: Main's window
        await pilot.press("escape", "S")  # the key that opened Setup closes it
        await pilot.pause()
        assert isinstance(app.screen, MainScreen)


async def test_a_click_on_set_closes_only_the_window(setup_app) -> None:
    """The button runs its action once (Window's on_button_pressed): Set sends
    once and leaves Setup showing, Load likewise."""
    app = setup_app
    async with app.run_test(size=(120, 40)) as pilot:
        await open_setup(pilot)
        await app.screen.run_action("tank(1)")
        await pilot.pause()
        app.screen.query_one("#f-TimeConst", Input).value = "80"
        await pilot.pause()
        await pilot.click("#set")
        await pilot.pause()
        assert isinstance(app.screen, SetupScreen)
        assert len(app.engine.sent(SetParams)) == 1
        await pilot.press("f")
        await pilot.pause()
        app.screen.query_one("#name", Input).value = "default"
        await pilot.click("#load")
        await pilot.pause()
        assert isinstance(app.screen, SetupScreen)
