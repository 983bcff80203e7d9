"""The disturbance pumps in the Faults window (issue 29): d1, d2 in percent of full
PWM where the process has them - an IST rig in Active, the simulated quadruple tank
in Simul.  On the virtual IST device through a pseudo-terminal, d1 typed in the
window goes out in the next pump frame (its 8-bit PWM), and Pause (a safe state)
sends a frame with all four pumps at 0."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Iterator

import pytest
from textual.widgets import Input
from uikit import Recording, make_app

from quadtank_tui.daq.ist import protocol as p
from quadtank_tui.daq.ist.backend import IstBackend
from quadtank_tui.daq.ist.config import IstConfig
from quadtank_tui.daq.ist.device import Firmware, ServedDevice
from quadtank_tui.engine import commands as c
from quadtank_tui.engine.backend import Levels4, Pair, ProcessBackend
from quadtank_tui.files.par import read_par
from quadtank_tui.ui.windows.faults import FaultWindow

ROOT = Path(__file__).parents[2]
PAR = ROOT / "params" / "ist-lisbon.par"


class IstStandIn(ProcessBackend):
    """An IST rig's face for a picture: steady levels, the disturbance pumps' duties
    8-bit quantized as the rig's are."""

    kind = "Active"
    description = "ist serial /dev/ttyUSB0"

    def __init__(self) -> None:
        self.disturbances: tuple[float, float] = (0.0, 0.0)

    def read_levels(self) -> Levels4:
        return (0.25, 0.25, 0.2, 0.2)

    def write_pumps(self, u: Pair) -> None:
        pass

    def safe_state(self) -> None:
        self.disturbances = (0.0, 0.0)

    def set_disturbances(self, d1: float | None, d2: float | None) -> None:
        old = self.disturbances
        self.disturbances = (old[0] if d1 is None else round(255 * d1) / 255,
                             old[1] if d2 is None else round(255 * d2) / 255)


def test_fault_window_in_active_on_an_ist_rig_80x24(snap_compare, make_engine) -> None:
    engine: Recording = make_engine(daq=IstStandIn())
    assert engine.submit(c.SetOperation("Active")).result().ok
    assert engine.submit(c.SetDisturbance(0.25, None)).result().ok
    assert snap_compare(make_app(engine), terminal_size=(80, 24), press=["F"])


def frames(device: ServedDevice) -> list[tuple[int, int, int, int]]:
    """u1, u2, d1, d2 of every pump frame the device received (whole: each starts '#16')."""
    data = bytes(device.pty.received).replace(p.REQUEST, b"")
    assert len(data) % p.PUMPS_FRAME_LEN == 0
    return [p.parse_pump_frame(data[i:i + p.PUMPS_FRAME_LEN]) for i in range(0, len(data), p.PUMPS_FRAME_LEN)]


@pytest.fixture
def device() -> Iterator[ServedDevice]:
    params = read_par(PAR).params
    d = ServedDevice(Firmware(IstConfig(port=""), params.quadtank_constants(), params.process_levels(), reset_s=0.0))
    try:
        yield d
    finally:
        d.close()


def settled(device: ServedDevice, frames: int) -> None:
    """Until the device has taken `frames` pump frames (its thread reads the pty)."""
    deadline = time.monotonic() + 5.0
    while device.firmware.frames < frames and time.monotonic() < deadline:
        time.sleep(0.005)
    assert device.firmware.frames == frames


@pytest.mark.wallclock  # a device thread on the wall clock
async def test_d1_typed_in_the_faults_window_goes_out_in_the_pump_frame(make_engine: Any, device: ServedDevice,
                                                                       tmp_path: Path) -> None:
    # The backend's clock is the loop's (a second a sample): the seconds the keys take
    # on a loaded machine are not the program stalling between samples.
    now = [0.0]
    backend = IstBackend(IstConfig(port=device.path, open_wait=0.05, timeout=1.5), clock=lambda: now[0])
    engine: Recording = make_engine(read_par(PAR).params, daq=backend)
    app = make_app(engine)
    try:
        async with app.run_test(size=(80, 24)) as pilot:
            await pilot.press("A", "r")             # Active, Run (Manual: the .par's inputs)
            engine.run_for(1.0)                     # a sample: a pump frame, no disturbance
            now[0] += 1.0
            settled(device, 1)
            await pilot.press("F")
            assert isinstance(app.screen, FaultWindow)
            assert app.screen.query_one("#d1", Input).value == "0"
            await pilot.click("#d1")
            await pilot.press("ctrl+a", "ctrl+k", *"50", "enter")  # 50 % of full PWM
            await pilot.pause()
            assert not isinstance(app.screen, FaultWindow)
            assert engine.sent(c.SetDisturbance) == [c.SetDisturbance(0.5, 0.0)]
            engine.run_for(1.0)                     # the next sample's frame carries it
            now[0] += 1.0
            settled(device, 2)
            u1, u2, d1, d2 = frames(device)[-1]
            assert engine.snapshot().fault is None, engine.snapshot().fault
            assert (d1, d2) == (128, 0) and u1 > 0 and u2 > 0  # round(0.5 * 255)
            assert device.firmware.pwm == (u1, u2, 128, 0)
            assert engine.snapshot().disturbances == (128 / 255, 0.0)
            await pilot.press("p")                  # Pause on a rig: the safe state
            await pilot.pause()
            settled(device, 3)
            assert frames(device)[-1] == (0, 0, 0, 0) and device.firmware.pwm == (0, 0, 0, 0)
            assert engine.snapshot().disturbances == (0.0, 0.0)
    finally:
        engine.engine.stop()


async def test_the_faults_window_drives_the_simulated_disturbance_pumps(engine: Recording) -> None:
    """Simul, the quadruple tank: d2 typed (a bad value first, named in the window),
    Set d sends both; the next window shows them as the engine has them (8-bit)."""
    app = make_app(engine)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("F")
        await pilot.click("#d2")
        await pilot.press("ctrl+a", "ctrl+k", *"120", "enter")
        await pilot.pause()
        assert isinstance(app.screen, FaultWindow)
        assert str(app.screen.query_one("#message").render()) == "d2 is a percent of full PWM, 0..100, got 120"
        await pilot.press("ctrl+a", "ctrl+k", *"50")
        await pilot.click("#disturb")
        await pilot.pause()
        assert engine.sent(c.SetDisturbance) == [c.SetDisturbance(0.0, 0.5)]
        assert engine.snapshot().disturbances == (0.0, 128 / 255)
        await pilot.press("F")
        assert app.screen.query_one("#d2", Input).value == "50.2"
