"""The virtual rig's model side with an injected clock (no sockets, no sleeping):
registers follow the nonlinear model, writes drive the pumps, the watchdog stops
them, the speed factor scales process time, and the sensors add what they say."""

from __future__ import annotations

import statistics

import pytest

from quadtank_tui.core.plants.johansson import P_MINUS, advance
from quadtank_tui.daq.config import load_daq_config
from quadtank_tui.daq.registers import decode, encode
from quadtank_tui.daq.rig import SensorModel, VirtualRig
from quadtank_tui.daq.server import IllegalAddress, answer

CONFIG = load_daq_config("labjack")
P = P_MINUS.params
H0 = P_MINUS.op.x


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def make(clock: FakeClock, **kw: object) -> VirtualRig:
    return VirtualRig(CONFIG, P, H0, clock=clock, **kw)  # type: ignore[arg-type]


def read_volts(rig: VirtualRig) -> list[float]:
    words = rig.read(0, 8)
    return [decode(CONFIG.inputs[f"AIN{i}"], words[2 * i:2 * i + 2]) for i in range(4)]


def write_volts(rig: VirtualRig, v1: float, v2: float) -> None:
    dac = CONFIG.outputs["DAC0"].register
    rig.write(1000, encode(dac, v1) + encode(dac, v2))


def test_registers_carry_kc_h_of_the_model() -> None:
    clock = FakeClock()
    rig = make(clock, watchdog=0.0)
    assert read_volts(rig) == pytest.approx([P.kc * h for h in H0], abs=1e-6)
    write_volts(rig, *P_MINUS.op.u)
    clock.now += 30.0
    expected = advance(H0, P_MINUS.op.u, 30.0, P)
    assert read_volts(rig) == pytest.approx([P.kc * h for h in expected], abs=1e-5)


def test_speed_factor_scales_process_time() -> None:
    clock = FakeClock()
    rig = make(clock, speed=20.0, watchdog=0.0)
    write_volts(rig, 4.0, 2.0)
    clock.now += 3.0
    rig.tick()
    assert rig.t == pytest.approx(60.0)
    assert rig.h == pytest.approx(advance(H0, (4.0, 2.0), 60.0, P), abs=1e-9)


def test_watchdog_stops_the_pumps_at_its_deadline() -> None:
    clock = FakeClock()
    events: list[str] = []
    rig = make(clock, watchdog=1.0, report=events.append)
    write_volts(rig, 5.0, 5.0)
    clock.now += 0.9
    rig.tick()
    assert rig.pump_volts == (5.0, 5.0)
    clock.now += 4.1          # 5 s after the write: pumps ran 1 s, then stood still 4 s
    rig.tick()
    assert rig.pump_volts == (0.0, 0.0) and rig.watchdog_trips == 1
    assert events == ["watchdog: no request for 1 s, DAC0 set to 0 V, DAC1 set to 0 V"]
    h_expected = advance(advance(H0, (5.0, 5.0), 1.0, P), (0.0, 0.0), 4.0, P)
    assert rig.h == pytest.approx(h_expected, abs=1e-9)
    assert rig.read(1000, 4) == encode(CONFIG.outputs["DAC0"].register, 0.0) * 2


def test_regular_requests_keep_the_watchdog_quiet() -> None:
    """As a LabJack's: any request clears its timer, a read as well as a write."""
    clock = FakeClock()
    rig = make(clock, watchdog=1.0)
    write_volts(rig, 3.0, 3.0)
    for i in range(10):
        clock.now += 0.5
        if i % 2:
            write_volts(rig, 3.0, 3.0)
        else:
            read_volts(rig)
    assert rig.pump_volts == (3.0, 3.0) and rig.watchdog_trips == 0


def test_the_watchdog_is_off_out_of_the_box_and_refuses_settings_while_on() -> None:
    """Off until armed (a LabJack's factory default); once on, its settings are
    refused (disable first, as the T-series datasheet says); the feed is not."""
    clock = FakeClock()
    rig = make(clock)
    write_volts(rig, 3.0, 3.0)
    clock.now += 60.0
    rig.tick()
    assert rig.pump_volts == (3.0, 3.0)
    wd = CONFIG.watchdog
    assert wd is not None
    on = make(clock, watchdog=1.0)
    assert on.read(61600, 2) == encode(wd.enable, 1) and on.read(61604, 2) == encode(wd.timeout_register, 1)
    with pytest.raises(IllegalAddress):
        on.write(61604, encode(wd.timeout_register, 5))
    assert wd.feed is not None
    on.write(61614, encode(wd.feed, 0))


def test_sensor_noise_offset_and_quantization() -> None:
    clock = FakeClock()
    noisy = make(clock, sensors=SensorModel(noise=0.01, offset=0.1, seed=7))
    samples = [read_volts(noisy)[0] for _ in range(400)]
    assert statistics.mean(samples) == pytest.approx(P.kc * H0[0] + 0.1, abs=0.003)
    assert statistics.stdev(samples) == pytest.approx(0.01, rel=0.15)
    again = make(FakeClock(), sensors=SensorModel(noise=0.01, offset=0.1, seed=7))
    assert [read_volts(again)[0] for _ in range(400)] == samples  # seeded: reproducible
    lsb = 10.0 / 4096
    coarse = make(clock, sensors=SensorModel(lsb=lsb))
    v = read_volts(coarse)
    assert all(abs(x / lsb - round(x / lsb)) < 1e-3 for x in v)


def test_pumps_clip_to_their_range_and_inputs_are_read_only() -> None:
    clock = FakeClock()
    rig = make(clock)
    write_volts(rig, 12.0, -3.0)
    assert rig.pump_volts == (10.0, 0.0)
    with pytest.raises(IllegalAddress):
        rig.write(0, [0, 0])
    with pytest.raises(IllegalAddress):
        rig.read(8, 2)


def test_protocol_answers_like_a_device() -> None:
    rig = make(FakeClock())
    ok = answer(rig, bytes([4, 0, 0, 0, 8]))
    assert ok[:2] == bytes([4, 16]) and len(ok) == 18
    assert answer(rig, bytes([3, 0, 0, 0, 8]))[2:] == ok[2:]      # one map, both read codes
    assert answer(rig, bytes([4, 0, 100, 0, 2])) == bytes([0x84, 2])  # illegal data address
    assert answer(rig, bytes([4, 0, 0, 0, 200])) == bytes([0x84, 3])  # count over 125
    assert answer(rig, bytes([16, 0, 0, 0, 2, 4, 0, 0, 0, 0])) == bytes([0x90, 2])  # AIN not writable
    assert answer(rig, bytes([43, 14, 1, 0])) == bytes([0xAB, 1])  # unsupported function
    assert answer(rig, bytes([16, 3, 232, 0, 2, 4, 0x40, 0x40, 0, 0])) == bytes([16, 3, 232, 0, 2])
    assert rig.pump_volts[0] == pytest.approx(3.0)
