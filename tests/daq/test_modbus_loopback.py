"""The Modbus TCP backend against a real virtual rig in a subprocess on loopback:
no mock of the protocol anywhere (pymodbus's client, our server, a TCP socket).

Timing assertions are generous bounds and conditions polled with a timeout; the
rig runs at a speed factor so minutes of process time take seconds.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.plants.johansson import steady_state_levels
from quadtank_tui.daq.config import load_daq_config
from quadtank_tui.daq.modbus import ModbusBackend
from quadtank_tui.engine.backend import BackendError
from quadtank_tui.files.par import read_par

ROOT = Path(__file__).parents[2]

PLANT = PRESET.quadtank_constants()
H0 = PRESET.operating_levels()


def normalized(h: tuple[float, ...]) -> list[float]:
    return [PLANT.kc * x / FULL_SCALE_V for x in h]


def test_levels_follow_the_model_to_its_steady_state(rig: Callable, poll: Callable) -> None:
    r = rig("--speed", "100", "--watchdog", "0")
    backend = ModbusBackend(r.config())
    try:
        # (At x100 the tanks drain for a while before the first sample: no start value.)
        v = (4.0, 2.5)
        target = normalized(steady_state_levels(v, PLANT))

        def settled() -> bool:
            backend.write_pumps((v[0] / FULL_SCALE_V, v[1] / FULL_SCALE_V))
            return backend.read_levels() == pytest.approx(target, abs=0.004)

        # ~10 slowest time constants of process time: under 10 s of wall time at x100.
        assert poll(settled, timeout=60.0), (backend.read_levels(), target)
        assert r.dacs() == pytest.approx(v)
    finally:
        backend.safe_state()
        backend.close()


def test_pump_writes_move_the_levels(rig: Callable, poll: Callable) -> None:
    r = rig("--speed", "10")
    backend = ModbusBackend(r.config())
    try:
        y0 = backend.read_levels()
        backend.write_pumps((0.8, 0.0))  # pump 1 feeds tanks 1 and 4; pump 2 off
        assert poll(lambda: (y := backend.read_levels())[0] > y0[0] + 0.02 and y[3] > y0[3] + 0.01
                    and y[1] < y0[1] and y[2] < y0[2], timeout=60.0)
        assert backend.applied == (0.8, 0.0) and backend.alarms == ()
    finally:
        backend.safe_state()
        backend.close()


def test_rig_killed_mid_run_then_back(rig: Callable) -> None:
    r = rig()
    backend = ModbusBackend(r.config())
    backend.read_levels()
    backend.write_pumps((0.3, 0.3))
    r.kill()
    t0 = time.monotonic()
    with pytest.raises(BackendError) as err:
        backend.read_levels()
    assert time.monotonic() - t0 < 15.0  # two tries of a refused connection: ms, but a loaded machine
    text = str(err.value)
    assert text.startswith(f"read of AIN0..AIN3 (input registers 0-7) at 127.0.0.1:{r.port} failed twice: ")
    assert "connection lost" in text or "cannot connect" in text
    with pytest.raises(BackendError, match="write of DAC0..DAC1"):
        backend.write_pumps((0.3, 0.3))
    backend.safe_state()  # must not raise on a dead link
    assert "cannot connect" in backend.safe_state_error

    back = rig(port=r.port)  # the link returns (a restarted device on the same address)
    y = backend.read_levels()
    assert y == pytest.approx(normalized(H0), abs=0.03)
    backend.safe_state()
    assert backend.safe_state_error == ""
    assert back.dacs() == (0.0, 0.0)
    backend.close()


def test_a_rig_slower_than_the_timeout(rig: Callable) -> None:
    r = rig("--reply-delay", "0.6")
    backend = ModbusBackend(r.config(timeout=0.15))
    t0 = time.monotonic()
    with pytest.raises(BackendError, match=r"failed: no answer within 0.15 s$"):
        backend.read_levels()
    assert time.monotonic() - t0 < 5.0  # 1 try of 0.15 s (a timeout is not waited twice), room for a loaded machine
    backend.safe_state()
    assert "no answer" in backend.safe_state_error
    patient = ModbusBackend(r.config(timeout=2.0))  # the same rig, a timeout it can meet
    assert len(patient.read_levels()) == 4
    patient.close()
    backend.close()


def test_rig_watchdog_stops_pumps_when_requests_stop(rig: Callable, poll: Callable) -> None:
    r = rig("--watchdog", "0.4", full_cli=True)  # the `quadtank rig` command itself, armed as a program left it
    backend = ModbusBackend(r.config())
    backend.write_pumps((0.5, 0.4))
    assert r.dacs() == pytest.approx((5.0, 4.0))
    assert "no request for 0.4 s, DAC0 set to 0 V, DAC1 set to 0 V" in r.wait_for("watchdog:", timeout=60.0)
    assert poll(lambda: r.dacs() == (0.0, 0.0), timeout=30.0)
    backend.close()


def test_interlock_trips_on_an_overfull_tank(rig: Callable, poll: Callable) -> None:
    r = rig("--speed", "20", "--watchdog", "0")
    backend = ModbusBackend(r.config())
    try:
        def overfull() -> bool:
            backend.read_levels()
            backend.write_pumps((0.95, 0.3))  # a controller insisting on filling tank 1
            return bool(backend.alarms)

        assert poll(overfull, timeout=60.0)
        assert backend.alarms[0] == "interlock: tank 1 above 95 % of its height, pump 1 cut"
        assert backend.applied == (0.0, 0.3)
        assert r.dacs() == pytest.approx((0.0, 3.0))
        y = backend.read_levels()
        assert y[0] >= 0.95 * 1.0 - 0.01 and y[0] <= 1.0

        # Once tank 1 is back below the release level, pump 1 runs again.
        def released() -> bool:
            backend.read_levels()
            backend.write_pumps((0.95, 0.3))
            return backend.alarms == ()

        assert poll(released, timeout=20.0)
        assert r.dacs()[0] == pytest.approx(9.5)
    finally:
        backend.safe_state()
        backend.close()


def test_one_lost_connection_is_absorbed_by_the_retry(rig: Callable) -> None:
    """The device restarts between two samples: the first try finds the old
    connection dead, the second connects afresh, and the sample succeeds."""
    r = rig("--par", str(ROOT / "params" / "nonminphase.par"))
    backend = ModbusBackend(r.config())
    try:
        nonmin = read_par(ROOT / "params" / "nonminphase.par").params
        y = backend.read_levels()   # the rig serves the .par's plant, from its levels
        assert y == pytest.approx(normalized(nonmin.operating_levels()), abs=0.03)
        r.kill()
        rig("--par", str(ROOT / "params" / "nonminphase.par"), port=r.port)
        assert backend.read_levels() == pytest.approx(y, abs=0.03)
        backend.write_pumps((0.3, 0.3))
    finally:
        backend.safe_state()
        backend.close()


def test_cable_cut_times_out_and_the_rig_watchdog_stops_the_pumps(
    rig: Callable, link_proxy: Callable, poll: Callable
) -> None:
    """The link goes silent (no reset): each try waits out the timeout, the sample
    fails with the reason, safe_state cannot reach the rig either, and the rig's own
    watchdog is what stops its pumps.  Reconnected, the next sample works (within
    the timeout of 0.5 s: a new connection through the relay's threads and the
    rig's answer; at 0.2 s it missed it at load 5, another test beside it)."""
    r = rig("--watchdog", "0.5")
    proxy = link_proxy(r.port)
    backend = ModbusBackend(r.config(timeout=0.5, port=proxy.port))
    try:
        backend.read_levels()
        backend.write_pumps((0.4, 0.4))
        assert r.dacs() == pytest.approx((4.0, 4.0))
        proxy.cut.set()
        t0 = time.monotonic()
        with pytest.raises(BackendError, match=r"read of AIN0..AIN3 .* failed: no answer within 0.5 s$"):
            backend.read_levels()
        assert 0.49 < time.monotonic() - t0 < 5.0       # one try of 0.5 s: a silence is not waited twice
        backend.safe_state()
        assert "no answer within 0.5 s" in backend.safe_state_error
        assert poll(lambda: r.dacs() == (0.0, 0.0), timeout=30.0)  # the rig's firmware
        proxy.cut.clear()
        assert len(backend.read_levels()) == 4
    finally:
        backend.close()


def test_a_plc_map_of_scaled_integers(rig: Callable) -> None:
    """params/daq-plc-example.yaml over the wire: 16-bit counts, one request per
    level (the addresses leave gaps), one write per pump."""
    from pymodbus.client import ModbusTcpClient

    path = ROOT / "params" / "daq-plc-example.yaml"
    r = rig("--map", str(path))  # the last --map wins: the rig serves the PLC's map
    backend = ModbusBackend(dataclasses.replace(load_daq_config(path), host="127.0.0.1", port=r.port))
    try:
        assert backend.read_levels() == pytest.approx(normalized(H0), abs=0.03)
        backend.write_pumps((0.5, 0.25))
        client = ModbusTcpClient("127.0.0.1", port=r.port, timeout=2.0)
        try:
            assert client.read_holding_registers(200, count=1, device_id=1).registers == [5000]
            assert client.read_holding_registers(210, count=1, device_id=1).registers == [2500]
        finally:
            client.close()
    finally:
        backend.safe_state()
        assert backend.safe_state_error == ""
        backend.close()
