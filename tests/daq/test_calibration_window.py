"""Pilot test: Setup's Calibration window on the virtual rig (loopback Modbus).

The rig's sensors read V = 0.45 h + 0.1 while the DAQ file says 2 cm/V and 0 cm;
the student types the heights on the scales (the model's steady levels).  The
window runs the procedure through the engine, fits, and writes the DAQ file and
the .par after asking; Cancel puts the pumps to 0."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Callable

import pytest
from textual.widgets import Input

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.core.plants.johansson import steady_state_levels
from quadtank_tui.daq.config import load_daq_config
from quadtank_tui.daq.modbus import ModbusBackend
from quadtank_tui.engine.commands import SetOperation
from quadtank_tui.engine.runner import Engine, build_engine
from quadtank_tui.files.par import read_par, write_par
from quadtank_tui.ui.app import build_app
from quadtank_tui.ui.screens.setup import SetupScreen
from quadtank_tui.ui.windows.base import ConfirmWindow
from quadtank_tui.ui.windows.calibration import CalibrationWindow
from daqkit import rig_yaml

ROOT = Path(__file__).parents[2]
SENSOR, OFFSET = 0.45, 0.1
VOLTS = (2.0, 2.5, 3.0)


@pytest.fixture
def rig_engine(rig: Callable, tmp_path: Path):
    params = PRESET.with_values({"SIMULATION.Sensor": SENSOR})
    folder = tmp_path / "params"
    folder.mkdir()
    par = write_par(folder / "lab.par", params)
    r = rig("--par", str(par), "--offset", str(OFFSET), "--speed", "4000")
    config = tmp_path / "rig.yaml"
    # The manual clock steps only while the test says so (not while it types the
    # heights): a watchdog timeout of a few samples would end Active control.
    config.write_text(rig_yaml(r.port) + "watchdog: {timeout: 3600}\n")
    engine = build_engine(None, daq=ModbusBackend(load_daq_config(config)), clock="manual",
                          params_dir=folder, logs_dir=tmp_path)
    assert engine.submit(SetOperation("Active")).result().ok
    yield engine, r, params, par, config
    engine.stop()


async def _until(pilot: Any, engine: Engine, window: CalibrationWindow, done: Callable[[], bool],
                 seconds: float = 30.0) -> None:
    """Step the engine (the manual clock only moves when told) and let Setup feed
    the window, until `done()`."""
    setup = next(s for s in pilot.app.screen_stack if isinstance(s, SetupScreen))
    deadline = time.monotonic() + seconds
    while not done():
        assert time.monotonic() < deadline, window.status
        for _ in range(5):
            engine.step()
        setup.refresh_view()
        await pilot.pause()


async def _open(pilot: Any) -> CalibrationWindow:
    """Setup, then its c key, as a user does."""
    await pilot.press("S", "c")
    await pilot.pause()
    window = pilot.app.screen
    assert isinstance(window, CalibrationWindow) and window.active_mode
    return window


async def test_the_window_recovers_the_rig_sensors_and_writes_them(rig_engine) -> None:
    engine, r, params, par, config = rig_engine
    app = build_app(engine, refresh_interval=0.05, wall_clock=lambda: 0.0)
    async with app.run_test(size=(100, 40)) as pilot:
        window = await _open(pilot)
        window.query_one("#cal-volts", Input).value = " ".join(map(str, VOLTS))
        window.query_one("#cal-window", Input).value = "2"
        window.query_one("#cal-tol", Input).value = "0.0003"
        await pilot.click("#start")
        for v in VOLTS:
            await _until(pilot, engine, window, lambda: window.status is not None and window.status.phase == "heights")
            assert r.dacs() == (v, v)
            assert "Read the heights" in str(window.query_one("#cal-progress").render())
            for i, h in enumerate(steady_state_levels((v, v), params.quadtank_constants()), start=1):
                window.query_one(f"#cal-h{i}", Input).value = f"{h:.4f}"
            record = window.query_one("#record")
            for _ in range(40):  # Textual's Button ignores a click during its last press (0.2 s)
                if not record.has_class("-active"):
                    break
                await pilot.pause(0.05)
            await pilot.click(record)
            await pilot.pause()
        await _until(pilot, engine, window, lambda: window.result is not None)
        assert r.dacs() == (0.0, 0.0)
        for cal in window.result.sensors.values():
            assert cal.gain == pytest.approx(1 / SENSOR, rel=2e-3)
            assert cal.offset == pytest.approx(-OFFSET / SENSOR, abs=0.02)
        shown = str(window.query_one("#cal-result").render())
        assert f"tank 1  gain {window.result.sensors[1].gain:.4f} cm/V" in shown and "a1 " in shown, shown
        window.query_one("#cal-par", Input).value = "lab"
        par_before, config_before = par.read_text(), config.read_text()
        await pilot.click("#write")
        await pilot.pause()
        await pilot.pause()
        assert isinstance(app.screen, ConfirmWindow)
        question = str(app.screen.query_one("#question").render())
        assert f"--- {config}" in question and f"--- {par}" in question and "+TimeConst1 " in question
        await pilot.press("y")
        await _until(pilot, engine, window, lambda: "Written into" in str(window.query_one("#message").render()))
    sensors = load_daq_config(config).sensors
    for cal, fit in zip(sensors, window.result.sensors.values()):
        assert (cal.gain, cal.offset) == pytest.approx((fit.gain, fit.offset), abs=1e-5)
    changed = [a for a, b in zip(config_before.splitlines(), config.read_text().splitlines()) if a != b]
    assert [a.split(":")[0].strip() for a in changed] == ["tank1", "tank2", "tank3", "tank4"]
    changed = [a for a, b in zip(par_before.splitlines(), par.read_text().splitlines()) if a != b]
    assert {a.split()[0] for a in changed} <= {f"TimeConst{i}" for i in range(1, 5)}, changed
    assert read_par(par).params.simulation.time_constants == pytest.approx(params.simulation.time_constants,
                                                                           rel=5e-3)


async def test_cancel_puts_the_pumps_to_0(rig_engine, poll: Callable) -> None:
    engine, r, _, _, _ = rig_engine
    app = build_app(engine, refresh_interval=0.05, wall_clock=lambda: 0.0)
    async with app.run_test(size=(100, 40)) as pilot:
        window = await _open(pilot)
        window.query_one("#cal-volts", Input).value = "4"
        window.query_one("#cal-tol", Input).value = "0.000000001"
        await pilot.click("#start")
        await _until(pilot, engine, window, lambda: window.status is not None and window.status.reads >= 3)
        assert poll(lambda: r.dacs() == (4.0, 4.0), 30.0)
        await pilot.click("#cancel")
        await pilot.pause()
        assert not isinstance(app.screen, CalibrationWindow)
        assert r.dacs() == (0.0, 0.0)
        s = engine.step()
        assert s.calibration is not None and s.calibration.phase == "cancelled" and s.u == (0.0, 0.0)
