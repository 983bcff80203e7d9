"""The virtual IST device behaves as the rig's firmware does (pure: a test clock)."""

from __future__ import annotations

import os
import select
import sys

import pytest

from quadtank_tui.daq.ist import protocol as p
from quadtank_tui.daq.ist.plant import IST_PLANT, IST_VOLTS
from quadtank_tui.daq.ist.config import IstConfig
from quadtank_tui.daq.ist.device import Firmware, PtyDevice
from quadtank_tui.core.plants.johansson import steady_state_levels

LEVELS = steady_state_levels(IST_VOLTS, IST_PLANT)


def firmware(clock: list[float], **kw: object) -> Firmware:
    return Firmware(IstConfig(port=""), IST_PLANT, LEVELS, clock=lambda: clock[0], reset_s=0.5, **kw)  # type: ignore[arg-type]


def test_levels_answer_is_the_sensors_codes_and_converts_back() -> None:
    clock = [0.0]
    fw = firmware(clock)
    reply = fw.feed(b"$")
    assert len(reply) == 14 and reply.startswith(b"#210")
    codes = p.parse_levels_reply(reply)
    assert codes[4] == 26667  # Vcc 5 V at 187.5 uV a code
    for i, code in enumerate(codes[:4]):
        h = p.level_cm(p.ratio(code, codes[4]), p.DH_DR[i], p.H0[i])
        assert h == pytest.approx(LEVELS[i], abs=0.01)  # a code is ~0.005 cm here


def test_watchdog_stops_all_four_pumps_two_seconds_after_the_last_request() -> None:
    clock = [0.0]
    fw = firmware(clock)
    fw.feed(b"$" + p.pump_frame(500, 600, 100, 200))
    assert fw.pwm == (500, 600, 100, 200)
    clock[0] = 1.9
    fw.feed(b"$")            # fed: 2 s more
    clock[0] = 3.8
    fw.tick()
    assert fw.pwm == (500, 600, 100, 200)
    fw.feed(p.pump_frame(700, 700, 0, 0))  # a pump frame does not feed it
    clock[0] = 3.95
    fw.tick()
    assert fw.pwm == (0, 0, 0, 0)
    fw.feed(p.pump_frame(700, 700, 0, 0))  # timed out: undone at once, as the loop does
    assert fw.pwm == (0, 0, 0, 0)


def test_a_truncated_frame_hangs_the_firmware_watchdog_included() -> None:
    clock = [0.0]
    fw = firmware(clock)
    fw.feed(b"$" + p.pump_frame(400, 400))
    fw.feed(p.pump_frame(800, 800)[:5])   # '#16' and 2 of 6 data bytes
    clock[0] = 10.0
    fw.tick()
    assert fw.hung and fw.pwm == (400, 400, 0, 0)  # the pumps run on: nothing stops them
    assert fw.feed(b"$$$$") == b""                 # taken as the frame's last 4 bytes, not answered
    assert not fw.hung and fw.pwm == (0, 0, 0, 0)  # the frame completed: the watchdog acts again


def test_opening_the_port_resets_the_nano() -> None:
    clock = [0.0]
    fw = firmware(clock)
    fw.feed(b"$" + p.pump_frame(400, 400))
    fw.reset()
    assert fw.pwm == (0, 0, 0, 0)
    assert fw.feed(b"$") == b""          # the bootloader hears nothing
    clock[0] = 0.6
    assert len(fw.feed(b"$")) == 14


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a Linux pty")
def test_a_late_pass_of_the_pty_device_counts_the_reset_from_when_the_port_was_closed() -> None:
    """The serving thread learns of the host's opening at its next pass, which a
    loaded machine may hold up past the reset (a fresh-clone CI, two tests side by
    side): the host, having waited its open_wait, has sent its '$' by then.  The reset
    counts from the last pass that saw the port closed, so that '$' is answered; one
    sent within the reset of that moment is still lost, as the bootloader loses it.
    Passes by hand on a test clock (serve_once), the host a plain file descriptor."""
    clock = [0.0]
    fw = Firmware(IstConfig(port=""), IST_PLANT, LEVELS, clock=lambda: clock[0], reset_s=0.05)
    device = PtyDevice(fw)
    try:
        device.serve_once(wait=0.01)     # nobody has the port open (EIO) at t = 0
        host = os.open(device.path, os.O_RDWR | os.O_NOCTTY)
        clock[0] = 0.1                   # the host waited its open_wait; the thread made no pass
        os.write(host, b"$")
        device.serve_once(wait=5.0)      # sees the opening and the '$' together
        assert select.select([host], [], [], 5.0)[0]
        assert p.parse_levels_reply(os.read(host, 64))[4] == 26667 and fw.requests == 1
        os.close(host)
        device.serve_once(wait=0.01)     # closed again (EIO) at t = 0.1
        host = os.open(device.path, os.O_RDWR | os.O_NOCTTY)
        clock[0] = 0.14                  # within the reset of the moment the port was closed
        os.write(host, b"$")
        device.serve_once(wait=5.0)
        assert bytes(device.received) == b"$$" and fw.requests == 1  # heard by the bootloader only
        os.close(host)
    finally:
        device.close()


def test_pumps_and_disturbances_drive_the_model() -> None:
    clock = [0.0]
    fw = firmware(clock)
    u = [pump.pwm(v) for pump, v in zip(p.PUMPS, IST_VOLTS)]
    fw.feed(b"$" + p.pump_frame(u[0], u[1]))
    for k in range(1, 11):               # 10 s at the operating point: the levels stay
        clock[0] = float(k)
        fw.feed(b"$")
    assert fw.h == pytest.approx(LEVELS, abs=0.1)
    fw.feed(p.pump_frame(u[0], u[1], 255, 0))  # disturbance pump 1 full: into tank 1 only
    # 3.137 * 39.01 * 0.05 * (1 - 0.0339) / (1 + 0.0012) = 5.90 cm^3/s
    assert fw.disturbance_flows() == pytest.approx((5.904, 0.0), abs=1e-3)
    before = fw.h
    clock[0] = 12.0
    fw.feed(b"$")
    assert fw.h[0] - before[0] == pytest.approx(2 * 5.904 / p.TANK_AREAS[0], rel=0.1)
    assert fw.h[1] == pytest.approx(before[1], abs=0.01)
