"""The IST rig's serial protocol and its conversions, as pure functions (no I/O).

Checked against the published interface, github.com/decenter2021/quadruple-tank-setup
at commit 6988f8cfc8a82e0d35ede605cbc56994f1a7a837:

- the Arduino Nano firmware (arduino-quadruple-tank/arduino-quadruple-tank.ino, .h):
  9600 baud; a level request is the byte ``$``; the answer is ``#210`` and ten bytes,
  the raw codes v1..v4 of the four level sensors and Vcc (ADS1115 at +-6.144 V,
  addresses 0x48 and 0x49), each 16 bits big-endian; a pump frame is ``#16`` and six
  bytes: u1, u2 (16 bits big-endian, 10-bit PWM 0..1023 on pins 9, 10) and d1, d2
  (8-bit PWM of the disturbance pumps on pins 5, 6); with no ``$`` for TIMEOUT =
  2000 ms the loop sets all four pumps to 0 on every pass (a pump frame does not
  feed it); after a ``#`` the firmware busy-waits for the rest of the frame.
- the Simulink interface (simulink/quadruple-simulink-block/quadruple_simulink_block.slx,
  its MATLAB Function blocks): queryArduino r_i = (Vcc - v_i) / v_i; water_level
  h_i = r_i dh_dr_i + h0_i; pwm_u PWM_i = 1023 (c1_i c3_i - c2_i k_i u_i) /
  (c1_i - k_i u_i) with u_i in volts; packPWM10bit saturates to 0..1023 and rounds.
- the identified constants (simulink/examples/LQR/identification/*.mat, read with
  scipy.io.loadmat): the values below, to the digits published.  The issue's
  rounded values (dh_dr -37.09 ..., c1 39.0/41.1, ...) agree with them.

The pump model the interface inverts is flow = k u = c1 (delta - c3) / (delta - c2)
cm^3/s at duty delta = PWM / 1023 (quadrupleSimObj.m uses the same law for the
disturbance pumps); u_max = 12 V (pump.mat).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

#: The level request, one byte.
REQUEST = b"$"
#: The start of every frame that carries data (the MATLAB binblock header).
HEADER = b"#"
#: What precedes the ten data bytes of a level answer: '#', 2 digits, "10".
LEVELS_PREFIX = b"#210"
LEVELS_REPLY_LEN = len(LEVELS_PREFIX) + 10
#: What precedes the six data bytes of a pump frame: '#', 1 digit, "6".
PUMPS_PREFIX = b"#16"
PUMPS_FRAME_LEN = len(PUMPS_PREFIX) + 6
#: Firmware constants (arduino-quadruple-tank.h): the watchdog, the PWM ranges.
WATCHDOG_S = 2.0
PWM_MAX = 1023          # the actuation pumps' 10-bit PWM (Timer 1, ICR1 = 0x03ff)
DISTURBANCE_MAX = 255   # the disturbance pumps' 8-bit analogWrite
BAUD = 9600
#: ADS1115 at PGA +-6.144 V (config words 0xC183..0xF183): 16-bit two's complement.
ADC_FULL_SCALE_V = 6.144
ADC_CODES = 32768

#: The rig's identified constants (identification/*.mat at the commit above).
DH_DR = (-37.09220720689878, -35.32990952649198, -34.83393235754071, -34.337882264285916)  # cm
H0 = (43.41720085620025, 41.12683033251579, 46.986494054285636, 39.345213148777496)         # cm
TANK_AREAS = (29.792531120331947, 29.78902953586498, 20.74026658633933, 20.492201363593914)  # cm^2
OUTLET_AREAS = (0.12414557559801581, 0.13503666974764247, 0.033270998679692694, 0.03310044501592099)  # cm^2
GAMMAS = (0.7568799039375005, 0.7563290071510692)
G = 981.0  # cm/s^2
#: per pump: c1 (cm^3/s), c2, c3 (duty), k (cm^3/(V s)) - pump.mat's c(:, i) and k(i)
PUMP_C1 = (39.010223117576864, 41.14911145107495)
PUMP_C2 = (-0.0012401118595907013, 0.009874055957904181)
PUMP_C3 = (0.03385649940174739, 0.043039695525520304)
PUMP_K = (3.1368993540698913, 3.3142304151663216)
PUMP_U_MAX = 12.0  # V


class FrameError(ValueError):
    """Bytes that are not the frame they should be; the message says how."""


@dataclass(frozen=True)
class PumpCurve:
    """One actuation pump's identified law, flow = c1 (d - c3) / (d - c2) cm^3/s at
    duty d, and its gain k (cm^3/(V s)) that makes volts of it."""

    c1: float
    c2: float
    c3: float
    k: float
    u_max: float = PUMP_U_MAX

    def pwm(self, volts: float) -> int:
        """The PWM code (0..1023) for `volts`: the interface's formula, rounded and
        saturated as packPWM10bit does.  0 V and below is PWM 0 (the pump off: the
        formula's 1023 c3 gives no flow either, but a PWM below the threshold is
        still a PWM)."""
        if not volts > 0.0:
            return 0
        ku = self.k * min(volts, self.u_max)
        x = PWM_MAX * (self.c1 * self.c3 - self.c2 * ku) / (self.c1 - ku)
        return int(min(PWM_MAX, max(0.0, x)) + 0.5)

    def flow(self, pwm: int) -> float:
        """cm^3/s the pump delivers at `pwm` (0 below its threshold)."""
        d = pwm / PWM_MAX
        if d <= max(self.c2, self.c3):
            return 0.0
        return self.c1 * (d - self.c3) / (d - self.c2)

    def volts(self, pwm: int) -> float:
        """The pump volts `pwm` is worth (flow / k): what the plant model takes."""
        return self.flow(pwm) / self.k


PUMPS = tuple(PumpCurve(c1, c2, c3, k) for c1, c2, c3, k in zip(PUMP_C1, PUMP_C2, PUMP_C3, PUMP_K))


# --- frames ---------------------------------------------------------------------------

def pump_frame(u1: int, u2: int, d1: int = 0, d2: int = 0) -> bytes:
    """The 9-byte pump frame: ``#16``, u1, u2 big-endian u16, d1, d2 bytes."""
    for name, x, hi in (("u1", u1, PWM_MAX), ("u2", u2, PWM_MAX), ("d1", d1, DISTURBANCE_MAX),
                        ("d2", d2, DISTURBANCE_MAX)):
        if not 0 <= x <= hi:
            raise FrameError(f"{name} = {x} is outside 0..{hi}")
    return PUMPS_PREFIX + struct.pack(">HHBB", u1, u2, d1, d2)


def parse_pump_frame(frame: bytes) -> tuple[int, int, int, int]:
    """u1, u2, d1, d2 of a whole pump frame."""
    if len(frame) != PUMPS_FRAME_LEN or not frame.startswith(PUMPS_PREFIX):
        raise FrameError(f"not a pump frame: {frame!r}")
    u1, u2, d1, d2 = struct.unpack(">HHBB", frame[len(PUMPS_PREFIX):])
    return u1, u2, d1, d2


def levels_reply(codes: tuple[int, int, int, int, int]) -> bytes:
    """The 14-byte answer to ``$``: ``#210`` and v1..v4, Vcc as big-endian u16."""
    return LEVELS_PREFIX + struct.pack(">5H", *(c & 0xFFFF for c in codes))


def parse_levels_reply(reply: bytes) -> tuple[int, int, int, int, int]:
    """v1..v4, Vcc codes of a whole answer; FrameError for a short or foreign one."""
    if len(reply) != LEVELS_REPLY_LEN:
        raise FrameError(f"short answer: {len(reply)} of {LEVELS_REPLY_LEN} bytes")
    if not reply.startswith(LEVELS_PREFIX):
        raise FrameError(f"the answer starts {reply[:4]!r}, not {LEVELS_PREFIX!r}")
    v1, v2, v3, v4, vcc = struct.unpack(">5H", reply[len(LEVELS_PREFIX):])
    return v1, v2, v3, v4, vcc


# --- conversions ---------------------------------------------------------------------

def ratio(code: int, vcc_code: int) -> float:
    """r = (Vcc - v) / v of one sensor (queryArduino); FrameError for v = 0 (a
    shorted or absent sensor: no ratio)."""
    if code == 0:
        raise FrameError("the sensor reads code 0 (no ratio: a shorted or disconnected sensor?)")
    return (vcc_code - code) / code


def level_cm(r: float, dh_dr: float, h0: float) -> float:
    """h = dh_dr r + h0, cm (water_level)."""
    return dh_dr * r + h0


def ratio_for_level(h: float, dh_dr: float, h0: float) -> float:
    """The inverse of level_cm: the sensor ratio at level h."""
    return (h - h0) / dh_dr


def adc_code(volts: float) -> int:
    """The ADS1115's code for `volts` at +-6.144 V full scale (saturating)."""
    return int(max(-ADC_CODES, min(ADC_CODES - 1, round(volts / ADC_FULL_SCALE_V * ADC_CODES))))


def adc_volts(code: int) -> float:
    """The volts of an ADS1115 code (187.5 uV per code)."""
    return code * ADC_FULL_SCALE_V / ADC_CODES
