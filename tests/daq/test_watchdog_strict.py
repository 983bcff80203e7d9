"""Strict mode of the device's watchdog, and the guard leaving another program's
arming alone (review of issue 24).  In process: a virtual rig on the test's clock
behind our Modbus server.

On a LabJack T-series any communication clears a non-strict watchdog: another
client reading every 0.5 s, or repeated `quadtank daq check`, kept the pumps at
3 V with the program and its guard gone.  Armed strict (WATCHDOG_STRICT_ENABLE_DEFAULT
61610, WATCHDOG_STRICT_KEY_DEFAULT 61612) with a key chosen per run, only a write
of that key to WATCHDOG_STRICT_CLEAR 61614 clears it.
"""

from __future__ import annotations

import dataclasses
import io
import json
import os
import subprocess
from pathlib import Path
from typing import Any, Callable, Sequence

import pytest
from pymodbus.client import ModbusTcpClient

from daqkit import recording_guard

import quadtank_tui.daq.modbus as modbus
from quadtank_tui.daq.config import DaqConfigError, parse_daq_config
from quadtank_tui.daq.guard import GuardSpec, guard_main
from quadtank_tui.daq.modbus import ModbusBackend
from quadtank_tui.daq.registers import Register, decode, encode
from quadtank_tui.daq.server import IllegalAddress
from test_device_watchdog import _rig_and_backend

KEY = Register("holding", 61612, "uint32")
ROOT = Path(__file__).parents[2]


def _other_client_reads(rig: Any, clock: Any, seconds: float, every: float = 0.3) -> None:
    """Another program (or `quadtank daq check`) reading the levels."""
    for _ in range(round(seconds / every)):
        clock.now += every
        rig.read(0, 8)
        rig.tick()


def test_only_the_runs_feed_clears_a_strict_watchdog(device: Callable[..., Any]) -> None:
    clock, rig, backend, written = _rig_and_backend(device)
    backend.arm(0.1)                                  # 1 s
    backend.write_pumps((0.3, 0.3))
    wd = rig.watchdog
    assert wd is not None and wd.enabled
    # paused, the loop still reads the levels each tick: its feed carries the key
    for _ in range(10):
        clock.now += 0.3
        backend.read_levels()
        rig.tick()
    assert rig.pump_volts == (3.0, 3.0) and rig.watchdog_trips == 0
    assert written.count(61614) == 10
    # the program silent; another client's reads, and a feed with another key, do not clear it
    clock.now += 0.3
    key = int(decode(KEY, [wd.words().get(a, 0) for a in KEY.span]))
    rig.write(61614, encode(KEY, float(key ^ 1)))
    _other_client_reads(rig, clock, 0.9)
    assert rig.pump_volts == (0.0, 0.0) and rig.watchdog_trips == 1
    assert wd.strict and key != 0
    backend.safe_state()
    backend.close()
    assert not wd.enabled


def test_a_second_run_chooses_another_key(device: Callable[..., Any]) -> None:
    keys = []
    for _ in range(2):
        clock, rig, backend, _ = _rig_and_backend(device)
        backend.arm(0.1)
        backend.read_levels()
        assert rig.watchdog is not None
        keys.append(decode(KEY, [rig.watchdog.words()[a] for a in KEY.span]))
        backend.close()
    assert keys[0] != keys[1]


def test_without_strict_registers_any_traffic_feeds_it(device: Callable[..., Any]) -> None:
    """A device configuration without them keeps non-strict behaviour, and says so."""
    text = ("preset: labjack\nhost: 10.0.0.2\nwatchdog:\n  strict_enable: null\n  strict_key: null\n")
    wd = parse_daq_config(text, name="x.yaml").watchdog
    assert wd is not None and not wd.strict
    assert wd.describe().endswith("; non-strict: any Modbus traffic feeds it")
    assert [w[0] for w in wd.arm_writes(1.0, {"DAC0": 0.0, "DAC1": 0.0}, 7)] == [
        "disable", "timeout", "DAC0 value on timeout", "DAC0 action", "DAC1 value on timeout", "DAC1 action",
        "enable"]
    with pytest.raises(DaqConfigError, match=r"^x\.yaml:3: watchdog\.strict_enable: strict mode needs "
                       r"strict_enable, strict_key and feed together$"):
        parse_daq_config("preset: labjack\nhost: 10.0.0.2\nwatchdog:\n  strict_key: null\n", name="x.yaml")


def _spec_of_the_run(device: Callable[..., Any], monkeypatch: pytest.MonkeyPatch) -> tuple[Any, Any, GuardSpec]:
    """A run driving the rig, and the spec its guard was given."""
    FakeGuard, started, released = recording_guard()

    monkeypatch.setattr(modbus, "Guard", FakeGuard)
    clock, rig, _, _ = _rig_and_backend(device)
    backend = ModbusBackend(device((0.0,) * 4, bank=rig).config(), clock=clock)
    backend.arm(0.1)
    backend.write_pumps((0.3, 0.4))
    assert rig.pump_volts == (3.0, 4.0) and len(started) == 1
    return rig, backend, started[0]


@pytest.mark.parametrize("taken_over", ["", "strict key", "timeout"])
def test_the_guard_disarms_only_a_watchdog_still_armed_as_the_dead_program_left_it(
        device: Callable[..., Any], monkeypatch: pytest.MonkeyPatch, taken_over: str) -> None:
    rig, backend, spec = _spec_of_the_run(device, monkeypatch)
    wd = rig.watchdog
    assert wd is not None and wd.enabled
    if taken_over:  # another program armed it since, with its own key (or timeout)
        rig.write(61600, encode(KEY, 0.0))
        rig.write({"strict key": 61612, "timeout": 61604}[taken_over], encode(KEY, 12345.0))
        rig.write(61600, encode(KEY, 1.0))
    dead = subprocess.Popen(["true"])
    dead.wait()
    r, w = os.pipe()
    os.write(w, json.dumps(dataclasses.asdict(dataclasses.replace(spec, pid=dead.pid))).encode() + b"\n")
    os.close(w)
    said = io.StringIO()
    with os.fdopen(r, "rb") as pipe:
        assert guard_main(pipe, said) == 0
    assert rig.pump_volts == (0.0, 0.0)
    assert wd.enabled is bool(taken_over)
    tail = (f"; its watchdog left as it is: {taken_over} no longer as armed by the program (another program "
            "has armed it since?)\n") if taken_over else "; its watchdog disarmed\n"
    assert said.getvalue().endswith(tail), said.getvalue()
    backend.close()


def test_close_leaves_a_watchdog_another_program_armed(rig: Callable[..., Any]) -> None:
    """Program A armed the device's watchdog; B (a take-over) armed it again with its
    own key and drives; A, stopping late (it was frozen, or stuck in a timeout),
    closes: its close reads the settings first, as the guard does, and leaves B's
    watchdog on.  Before, A switched it off and B drove unprotected.  A real
    `quadtank rig` subprocess on loopback."""
    r = rig("--speed", "20")
    cfg = r.config()
    wd = cfg.watchdog
    assert wd is not None and wd.strict

    def enabled() -> float:
        client = ModbusTcpClient("127.0.0.1", port=r.port, timeout=2.0)
        try:
            rr = client.read_holding_registers(wd.enable.address, count=wd.enable.count, device_id=1)
            return decode(wd.enable, rr.registers)
        finally:
            client.close()

    a = ModbusBackend(cfg, guard=False)
    a.arm(0.1)
    a.read_levels()
    b = ModbusBackend(cfg, guard=False)
    b.arm(0.1)
    b.read_levels()
    b.write_pumps((0.3, 0.3))
    assert enabled() == 1.0 and a._key != b._key
    a.safe_state()
    a.close()
    assert enabled() == 1.0                           # B's watchdog still on
    b.safe_state()
    b.close()
    assert enabled() == 0.0                           # B's own close: still its settings, disarmed


def test_a_pause_whose_zero_keeps_failing_leaves_the_watchdog_unfed(device: Callable[..., Any], tmp_path: Any) -> None:
    """Pause while the device refuses every write of 0 to the pumps: the paused loop
    tries again each tick and neither reads nor feeds, so the device's strict
    watchdog (1 s at TSamp 0.1) stops the pumps within its timeout.  Before, the
    paused loop read the levels and fed it: the pumps ran on at 3 V."""
    from quadtank_tui.engine.commands import SetOperation, SetState
    from quadtank_tui.engine.runner import build_engine

    clock, rig, backend, written = _rig_and_backend(device)
    write = rig.write

    def refusing(address: int, values: Sequence[int]) -> None:
        if address in (1000, 1002) and decode(Register("holding", 1000, "float32", "big"), list(values[:2])) == 0.0:
            raise IllegalAddress(address)
        write(address, values)

    engine = build_engine(None, daq=backend, params_dir=ROOT / "params", logs_dir=tmp_path, clock="virtual",
                          speed=20.0)
    try:
        for command in (SetOperation("Active"), SetState("Run")):
            assert engine.submit(command).result().ok
        for _ in range(5):
            clock.now += 0.1
            engine.step()
            rig.tick()
        assert rig.pump_volts == (3.0, 3.0)
        rig.write = refusing  # type: ignore[method-assign]
        assert engine.submit(SetState("Pause")).result().ok
        fault = engine.snapshot().fault
        assert fault is not None and "pumps NOT confirmed at 0 (left to the device's watchdog to stop them)" in fault
        written.clear()
        t = 0.0
        while rig.pump_volts != (0.0, 0.0) and t < 3.0:
            clock.now += 0.1
            t += 0.1
            engine.step()
            rig.tick()
        assert rig.pump_volts == (0.0, 0.0) and rig.watchdog_trips == 1
        assert round(t, 6) <= 1.0, t                  # within its timeout of the failed zero (fed last before it)
        assert 61614 not in written                   # never fed while unconfirmed
    finally:
        rig.write = write  # type: ignore[method-assign]
        engine.stop()
