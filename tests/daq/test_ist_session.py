"""The TUI and sessions on an IST rig, as on a Modbus one: `quadtank --daq
daq-ist.yaml` starts a session process that takes the rig's lock under its serial
device's real path, opens the port itself and drives the virtual device in Active
(the TUI here is Textual's pilot on the session's client, pressing the keys); a
second session or terminal on the same device - under another name for it too - is
refused naming the device; the session killed, the device's own watchdog stops the
pumps within 2 s.  `--no-session` drives it from a private session whose end (the
TUI's Exit) stops the pumps and frees the rig.

The device (daq/ist/device.py) is served by a thread of this process on the wall
clock; the session process opens its pseudo-terminal."""

from __future__ import annotations

import asyncio
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any, Callable, Iterator

import pytest

from quadtank_tui.cli import main
from quadtank_tui.commands import sessions as sessions_command
from quadtank_tui.daq.ist.plant import IST_PLANT
from quadtank_tui.daq.ist.config import IstConfig
from quadtank_tui.daq.ist.device import Firmware, ServedDevice
from quadtank_tui.engine.runner import engine_spec
from quadtank_tui.session.client import SessionClient, stop_session_at
from quadtank_tui.session.launch import SessionSpec, SessionStartError, start_session
from quadtank_tui.files.proc import pid_alive
from quadtank_tui.session.runtime import list_sessions

pytestmark = [pytest.mark.wallclock, pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a Linux pty")]

ROOT = Path(__file__).parents[2]
PAR = ROOT / "params" / "ist-lisbon.par"
#: The device's water, far from the .par's operating point (6 V: 9.7-12.1 cm), so a
#: level the session shows is the device's, not the simulator's.
LEVELS = (20.0, 16.0, 8.0, 5.0)


@pytest.fixture
def device() -> Iterator[ServedDevice]:
    """The virtual IST device served by a thread of this process, its water far from
    the .par's operating point."""
    d = ServedDevice(Firmware(IstConfig(port=""), IST_PLANT, LEVELS, reset_s=0.05))
    try:
        yield d
    finally:
        d.close()


@pytest.fixture
def lab(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A runtime folder (sessions, locks) of the test's own, and a lab whose
    unattended Active sessions keep running for 10 min (without a policy the last
    client's leaving pauses them, pumps at 0: the kill below would find them off)."""
    runtime = tmp_path / "run"
    monkeypatch.setenv("QUADTANK_RUNTIME", str(runtime))
    (tmp_path / "lab.yaml").write_text("unattended:\n  grace_minutes: 10\n")
    monkeypatch.setenv("QUADTANK_LAB", str(tmp_path / "lab.yaml"))
    monkeypatch.chdir(tmp_path)
    return runtime


def ist_yaml(tmp_path: Path, port: str, name: str = "ist.yaml") -> Path:
    """params/daq-ist.yaml pointed at `port`, a short open wait (the device resets in 0.05 s)."""
    text = (ROOT / "params" / "daq-ist.yaml").read_text()
    text = text.replace("port: /dev/ttyUSB0", f"port: {port}").replace("open_wait: 2.0", "open_wait: 0.1")
    path = tmp_path / name
    path.write_text(text)
    return path


def test_the_tui_drives_the_ist_device_through_its_session_and_a_second_one_is_refused(
        device: ServedDevice, lab: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str], poll: Callable[..., bool]) -> None:
    cfg = ist_yaml(tmp_path, device.path)
    seen: dict[str, Any] = {}

    def tui(client: SessionClient, refresh: float) -> int:  # the TUI, pressing keys like a user
        from quadtank_tui.ui.app import build_app

        async def drive() -> None:
            app = build_app(client, refresh_interval=0.05)
            async with app.run_test(size=(120, 40)) as pilot:
                await pilot.press("A")
                for _ in range(500):
                    if client.snapshot().operation == "Active":
                        break
                    await pilot.pause(0.02)
                await pilot.press("i", "ctrl+a", "ctrl+k", *"0.5", "enter")  # Manual: u1's mean 0.5
                await pilot.press("r")
                for _ in range(1000):  # the input's mean moves to 0.5 progressively
                    if client.snapshot().u[0] > 0.5 - 1e-9:
                        break
                    await pilot.pause(0.02)
                await pilot.pause(1.2)  # a sample (1 s) on: its frame is on the device
                seen["snap"] = client.snapshot()
                seen["levels"] = device.firmware.h
                seen["pwm"] = device.firmware.pwm
        asyncio.run(drive())
        client.close()  # detaches: the session keeps the rig
        return 0

    monkeypatch.setattr(sessions_command, "run_tui_on", tui)
    assert main(["--par", str(PAR), "--daq", str(cfg)]) == 0
    (info,) = list_sessions(lab)
    key = f"serial:{os.path.realpath(device.path)}"
    try:
        snap = seen["snap"]
        assert (snap.operation, snap.state, snap.fault) == ("Active", "Run", None)
        assert snap.backend == f"ist serial {device.path}"
        # The levels are the device's (0.25 V/cm, normalized by 10 V), to its ADC's
        # quantization and the water's motion over the sample's age (< 0.1 cm on a quiet
        # machine; 0.11 cm seen at load 12, so 0.2 cm); the simulator's water started
        # elsewhere (the .par's 9.7-12.1 cm, the device's 20, 16, 8, 5: 1.4 cm apart or more).
        for y, h in zip(snap.y, seen["levels"]):
            assert y == pytest.approx(0.025 * h, abs=0.005)
        # u1 = 0.5 (5 V) went to pump 1 as the identified law's PWM (59 of 1023)
        pumps = IstConfig(port="").pumps
        assert seen["pwm"][:2] == (pumps[0].pwm(5.0), pumps[1].pwm(10.0 * snap.u[1])) and seen["pwm"][0] == 59
        capsys.readouterr()

        # A second session on the same device, under another name for it: refused by
        # the lock, naming the device and the session that drives it.
        link = tmp_path / "ttyIST"
        link.symlink_to(device.path)
        other = ist_yaml(tmp_path, str(link), "other.yaml")
        spec = engine_spec(PAR, clock="realtime", params_dir=tmp_path / "params", logs_dir=tmp_path / "logs")
        with pytest.raises(SessionStartError) as refused:
            start_session(SessionSpec(spec, str(lab), str(other)))
        assert str(refused.value).startswith(f"the rig at {key} is driven by {info.owner} "
                                             f"(pid {info.pid}, session {info.id}) since ")
        # and so is a terminal of its own (--no-session)
        assert main(["--no-session", "--par", str(PAR), "--daq", str(other)]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"quadtank: error: the rig at {key} is driven by {info.owner} "
                              f"(pid {info.pid}, session {info.id}) since ") and err.count("\n") == 1
        assert device.firmware.pwm[0] > 0  # the refused programs never touched the rig

        # The session, detached, killed: nothing stops the pumps but the device's own
        # watchdog, within 2 s of the last level request (the session polled every
        # sample of 1 s and its keep-alive every 1 s).
        assert device.firmware.pwm[0] > 0  # still pumping, detached (the lab's grace)
        os.kill(info.pid, signal.SIGKILL)
        t0 = time.monotonic()
        assert poll(lambda: device.firmware.pwm == (0, 0, 0, 0), 5.0, 0.02)
        took = time.monotonic() - t0
        print(f"SIGKILL -> pumps 0: {took:.2f} s")
        assert took < 3.0  # the watchdog's 2 s after the last request (1.4-2.0 s measured), the device thread's lag under load
    finally:
        if pid_alive(info.pid):
            stop_session_at(info.socket)


def test_no_session_drives_the_ist_device_and_stops_it_when_the_tui_ends(
        device: ServedDevice, lab: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        poll: Callable[..., bool]) -> None:
    """`quadtank --no-session --daq`: a private session on the device (the launcher
    holds the lock under the device's real path); the TUI's Exit stops it, all four
    pumps at 0, and the rig is free again."""
    from quadtank_tui.session.lab import load_lab_config
    from quadtank_tui.session.lock import holder_of
    from quadtank_tui.ui.app import QuadTankApp

    cfg = ist_yaml(tmp_path, device.path)
    key = f"serial:{os.path.realpath(device.path)}"
    seen: dict[str, Any] = {}

    def run(app: QuadTankApp, *args: Any, **kwargs: Any) -> None:  # the terminal: the pilot's keys
        async def drive() -> None:
            async with app.run_test(size=(120, 40)) as pilot:
                await pilot.press("A", "r")
                for _ in range(1000):
                    if device.firmware.pwm[0] > 0:
                        break
                    await pilot.pause(0.02)
                seen["pwm"] = device.firmware.pwm
                seen["holder"] = holder_of(key, load_lab_config())
                seen["sessions"] = list_sessions(lab)
        asyncio.run(drive())

    monkeypatch.setattr(QuadTankApp, "run", run)
    assert main(["--no-session", "--par", str(PAR), "--daq", str(cfg)]) == 0
    assert seen["pwm"][0] > 0 and seen["sessions"] == []  # it pumped; a private session is not listed
    assert seen["holder"] is not None and seen["holder"].pid == os.getpid()  # the launcher holds the rig
    # the TUI ended: pumps at 0 by the session's zero frame, not the watchdog 2 s later
    assert poll(lambda: device.firmware.pwm == (0, 0, 0, 0), 1.0, 0.02)
    assert holder_of(key, load_lab_config()) is None
