"""The IST rig's frames and conversions against hand-computed values (issue 29's
constants; the published ones in daq/ist/protocol.py agree to the digits shown)."""

from __future__ import annotations

import pytest

from quadtank_tui.daq.ist import protocol as p


def test_pump_frame_is_nine_bytes_big_endian() -> None:
    # '#', '1', '6', u1 = 0x0102, u2 = 0x03FF, d1 = 0x7F, d2 = 0xFF
    assert p.pump_frame(258, 1023, 127, 255) == b"#16\x01\x02\x03\xff\x7f\xff"
    assert p.parse_pump_frame(b"#16\x01\x02\x03\xff\x7f\xff") == (258, 1023, 127, 255)
    assert p.pump_frame(0, 0) == b"#16" + bytes(6)


@pytest.mark.parametrize("args", [(1024, 0, 0, 0), (0, -1, 0, 0), (0, 0, 256, 0), (0, 0, 0, 300)])
def test_pump_frame_refuses_out_of_range(args: tuple[int, int, int, int]) -> None:
    with pytest.raises(p.FrameError):
        p.pump_frame(*args)


def test_levels_reply_round_trip_and_short_answers() -> None:
    reply = p.levels_reply((20000, 15000, 0x1234, 1, 30000))
    assert reply == b"#210" + bytes([0x4E, 0x20, 0x3A, 0x98, 0x12, 0x34, 0x00, 0x01, 0x75, 0x30])
    assert p.parse_levels_reply(reply) == (20000, 15000, 0x1234, 1, 30000)
    with pytest.raises(p.FrameError, match="short answer: 13 of 14 bytes"):
        p.parse_levels_reply(reply[:-1])
    with pytest.raises(p.FrameError, match="not b'#210'"):
        p.parse_levels_reply(b"#211" + reply[4:])


def test_level_from_codes_by_hand() -> None:
    # v = 20000, Vcc = 30000: r = (30000 - 20000) / 20000 = 0.5;
    # h1 = -37.09 * 0.5 + 43.42 = 24.875 cm (issue's constants)
    r = p.ratio(20000, 30000)
    assert r == 0.5
    assert p.level_cm(r, -37.09, 43.42) == pytest.approx(24.875, abs=1e-12)
    assert p.level_cm(r, p.DH_DR[0], p.H0[0]) == pytest.approx(24.875, abs=0.01)
    # v = 15000: r = 1; h4 = -34.34 + 39.35 = 5.01 cm
    assert p.level_cm(p.ratio(15000, 30000), -34.34, 39.35) == pytest.approx(5.01, abs=1e-12)
    assert p.level_cm(1.0, p.DH_DR[3], p.H0[3]) == pytest.approx(5.01, abs=0.01)
    assert p.ratio_for_level(24.875, -37.09, 43.42) == pytest.approx(0.5)
    with pytest.raises(p.FrameError, match="code 0"):
        p.ratio(0, 30000)


def test_pwm_from_volts_by_hand() -> None:
    # pump 1, 6 V (issue's constants): k u = 3.14 * 6 = 18.84;
    # 1023 (39.0 * 0.034 + 0.0012 * 18.84) / (39.0 - 18.84) = 1023 * 1.348608 / 20.16 = 68.43 -> 68
    issue1 = p.PumpCurve(39.0, -0.0012, 0.034, 3.14)
    assert issue1.pwm(6.0) == 68
    assert p.PUMPS[0].pwm(6.0) == 68        # published constants: 68.11 -> 68
    # pump 2, 6 V: k u = 3.31 * 6 = 19.86; 1023 (41.1 * 0.043 - 0.0099 * 19.86) / (41.1 - 19.86)
    # = 1023 * 1.570686 / 21.24 = 75.65 -> 76
    assert p.PumpCurve(41.1, 0.0099, 0.043, 3.31).pwm(6.0) == 76
    assert p.PUMPS[1].pwm(6.0) == 76        # published: 75.76 -> 76
    # pump 1, 10 V: 1023 (1.326 + 0.03768) / (39.0 - 31.4) = 183.56 -> 184 (published: 182.03 -> 182)
    assert issue1.pwm(10.0) == 184
    assert p.PUMPS[0].pwm(10.0) == 182
    # u_max 12 V is PWM 1023 for both pumps (the identification's design); beyond, saturated
    assert p.PUMPS[0].pwm(12.0) == p.PUMPS[1].pwm(12.0) == 1023
    assert p.PUMPS[0].pwm(50.0) == 1023
    assert p.PUMPS[0].pwm(0.0) == p.PUMPS[0].pwm(-1.0) == 0


def test_pwm_and_flow_are_inverse() -> None:
    # the device's law: flow = c1 (d - c3) / (d - c2); back to volts within one PWM step
    for pump in p.PUMPS:
        for volts in (1.0, 3.0, 6.0, 9.5):
            back = pump.volts(pump.pwm(volts))
            step = pump.volts(pump.pwm(volts) + 1) - back
            assert abs(back - volts) <= step
        assert pump.flow(0) == 0.0
        assert pump.flow(30) == 0.0          # below the threshold 1023 c3: no flow


def test_adc_quantization() -> None:
    # 6.144 V full scale, 16 bits: 187.5 uV per code; 5 V = 26666.67 -> 26667
    assert p.adc_code(5.0) == 26667
    assert p.adc_volts(1) == pytest.approx(187.5e-6)
    assert p.adc_code(7.0) == 32767        # saturates
