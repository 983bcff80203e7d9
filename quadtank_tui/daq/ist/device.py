"""The virtual IST rig: the Arduino firmware's behaviour over our nonlinear model,
served on a pseudo-terminal (`quadtank rig --protocol ist`).

:class:`Firmware` is the Nano's loop, byte for byte (arduino-quadruple-tank.ino at
the commit protocol.py cites), on an injected clock:

- ``$``: the five ADS1115 codes (the levels through each sensor's ratio law, Vcc,
  quantized at +-6.144 V / 16 bits) answered as ``#210`` + 10 bytes; it feeds the
  watchdog;
- ``#``: the next eight bytes are read whatever they are (the firmware skips the two
  metadata bytes unchecked) and become u1, u2, d1, d2; until they have all come the
  loop waits - watchdog included: a truncated frame hangs it with the pumps as they
  were (`hung` says so);
- any other byte is ignored;
- every pass of the loop: no ``$`` for more than 2 s sets all four pumps to 0 (so a
  pump frame without a recent ``$`` is undone at once);
- opening the port resets the Nano: for `reset_s` it hears nothing (the bootloader),
  then starts with the pumps off.  The pseudo-terminal tells the serving thread of an
  opening only at its next pass, so the reset is counted from the last moment the
  port was seen closed, the earliest the host can have opened it (PtyDevice): a
  host that waited its `open_wait` is never refused because this thread was late.

The plant is core.plants.johansson's quadruple tank (the .par's constants) driven by the
pumps' volts of the identified law (protocol.PumpCurve.volts of each PWM code); the
disturbance pumps pour into tanks 1 and 2 by the law of the rig's own simulator
(core.disturbance, with the configuration's pump 1 constants, d = PWM / 255), in
the model's equations as the simulator's Simul disturbance is (core.faults.advance).
"""

from __future__ import annotations

import errno
import math
import os
import select
import threading
import time
import tty
from dataclasses import dataclass
from typing import Callable, Sequence

from quadtank_tui.core import faults as fx
from quadtank_tui.core.disturbance import DisturbancePumps
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.plants.johansson import PlantParams
from quadtank_tui.core.plants import QuadTank
from quadtank_tui.daq.ist import protocol as p
from quadtank_tui.daq.ist.config import IstConfig

#: Nominal Vcc of the sensors' divider (the Nano's USB 5 V), V.
VCC = 5.0
#: Wall seconds between two passes of the served loop when no byte comes.
TICK_S = 0.02


#: No fault acts on the IST rig's tanks (its disturbances are pumps: `inflow`).
NO_FAULTS = fx.Faults()


@dataclass(frozen=True)
class PwmPumpedTanks(QuadTank):
    """The quadruple tank as the Nano drives it: each pump takes the volts of its
    identified law, up to the law's volts at full duty (`top`, 12 V with the
    published constants), not the Lund amplifiers' 0..10 V.  So a disturbance pump
    switched on adds its flow and changes nothing else (core.faults.advance
    saturates the pumps at the plant's range)."""

    top: float = FULL_SCALE_V

    @property
    def pump_max(self) -> float:
        return self.top


class Firmware:
    """The Nano's loop and the tanks behind it, on `clock` (wall s) times `speed`."""

    def __init__(self, config: IstConfig, plant: PlantParams, levels_cm: Sequence[float], *,
                 clock: Callable[[], float] = time.monotonic, speed: float = 1.0, reset_s: float = 1.0,
                 vcc: float = VCC, report: Callable[[str], None] = lambda text: None) -> None:
        if not speed > 0 or not math.isfinite(speed):
            raise ValueError(f"speed must be a number > 0, got {speed}")
        self.config, self.plant, self.speed, self.vcc = config, plant, speed, vcc
        #: the tanks as the pumps' law drives them, up to its volts at full duty
        self.tanks = PwmPumpedTanks(plant, top=max(c.volts(p.PWM_MAX) for c in config.pumps[:2]))
        self.h = tuple(float(x) for x in levels_cm)
        self.clock, self.reset_s, self.report = clock, reset_s, report
        #: u1, u2 (10-bit), d1, d2 (8-bit) as the pins have them
        self.pwm: tuple[int, int, int, int] = (0, 0, 0, 0)
        self._frame: bytearray | None = None  # bytes of a pump frame after its '#'
        self._t = clock()
        self._booted_at = self._t
        self._prev_com = self._t  # millis() and prevCom both start at 0
        self.requests = 0
        self.frames = 0
        #: answers lost on the line (a test's broken cable): '$' is heard, never answered
        self.mute = False

    @property
    def hung(self) -> bool:
        """In the middle of a pump frame: the loop waits for its bytes, watchdog included."""
        return self._frame is not None

    def reset(self, opened_at: float | None = None) -> None:
        """The port was opened (DTR) at `opened_at` (the clock's time; now if None):
        the Nano restarts, pumps off, deaf for `reset_s` from then."""
        self._advance()
        self.pwm, self._frame = (0, 0, 0, 0), None
        since = self._t if opened_at is None else min(opened_at, self._t)
        self._booted_at = self._prev_com = since + self.reset_s

    def feed(self, data: bytes) -> bytes:
        """The bytes the host sent; returns the firmware's answers."""
        self._advance()
        out = bytearray()
        if self._t < self._booted_at:
            return b""  # the bootloader: what comes now is lost
        for b in data:
            if self._frame is not None:
                self._frame.append(b)
                if len(self._frame) == 8:
                    u1, u2, d1, d2 = p.parse_pump_frame(p.PUMPS_PREFIX + bytes(self._frame[2:]))
                    # OCR1x above TOP (1023) is a duty of 100 %
                    self.pwm, self._frame = (min(u1, p.PWM_MAX), min(u2, p.PWM_MAX), d1, d2), None
                    self.frames += 1
                    self._watchdog()
                continue
            if b == p.REQUEST[0]:
                out += b"" if self.mute else p.levels_reply(self.codes())
                self._prev_com = self._t
                self.requests += 1
            elif b == p.HEADER[0]:
                self._frame = bytearray()
            self._watchdog()
        return bytes(out)

    def tick(self) -> None:
        """A pass of the loop with no byte: time passes, the watchdog looks."""
        self._advance()
        self._watchdog()

    def _watchdog(self) -> None:
        if self._frame is None and self._t - self._prev_com > p.WATCHDOG_S and self.pwm != (0, 0, 0, 0):
            self.pwm = (0, 0, 0, 0)
            self.report(f"watchdog: no '$' for {self._t - self._prev_com:.1f} s: all pumps to 0")

    def codes(self) -> tuple[int, int, int, int, int]:
        """The ADS1115 codes of v1..v4 and Vcc now."""
        codes = []
        for s, h in zip(self.config.sensors, self.h):
            r = p.ratio_for_level(h, s.dh_dr, s.h0)
            codes.append(p.adc_code(self.vcc / (1.0 + r)) if r > -1.0 else p.adc_code(1e9))
        return codes[0], codes[1], codes[2], codes[3], p.adc_code(self.vcc)

    def volts(self) -> tuple[float, float]:
        """The actuation pumps' volts now (the identified law of their PWM)."""
        return (self.config.pumps[0].volts(self.pwm[0]), self.config.pumps[1].volts(self.pwm[1]))

    def disturbance_flows(self) -> tuple[float, float]:
        """cm^3/s of the two disturbance pumps into tanks 1 and 2."""
        c = self.config.pumps[0]
        pumps = DisturbancePumps(c1=c.c1, c2=c.c2, c3=c.c3, k=c.k)
        return (pumps.flow(self.pwm[2] / p.DISTURBANCE_MAX), pumps.flow(self.pwm[3] / p.DISTURBANCE_MAX))

    def _advance(self) -> None:
        now = self.clock()
        dt = (now - self._t) * self.speed
        self._t = now
        if dt <= 0:
            return
        q = self.disturbance_flows()
        self.h = fx.advance(self.tanks, NO_FAULTS, self.h, self.volts(), dt, (q[0], q[1], 0.0, 0.0))

    def status(self) -> str:
        return ("h = " + " ".join(f"{x:6.2f}" for x in self.h) + " cm   pwm u = "
                f"{self.pwm[0]:4d} {self.pwm[1]:4d}  d = {self.pwm[2]:3d} {self.pwm[3]:3d}"
                + ("   HUNG in a pump frame" if self.hung else ""))


class PtyDevice:
    """A pseudo-terminal whose far end is `firmware`: `path` is what the host opens.

    The host's opening is seen at the next pass (a read no longer fails with EIO),
    which a loaded machine may hold up for longer than the Nano's reset: the host,
    having waited its `open_wait`, has sent its first '$' by then.  So the reset is
    counted from the last pass that saw the port closed (`_closed_at`), the earliest
    the host can have opened it.  Counted from the pass that saw the opening, a
    thread held 0.2 s lost that '$' though the host had waited twice the reset: a
    "no answer" fault, the pumps left at 0 (two tests side by side in a CI run)."""

    def __init__(self, firmware: Firmware) -> None:
        self.firmware = firmware
        self.master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no line discipline: bytes as a USB serial port passes them
        self.path = os.ttyname(slave)
        os.close(slave)  # the host's open is then seen (EIO ends): the Nano's reset
        self._host = False
        #: the firmware's time when the port was last seen closed (nobody had it open)
        self._closed_at = firmware.clock()
        #: every byte the host sent, in order (tests read it)
        self.received = bytearray()

    def serve_once(self, wait: float = TICK_S) -> None:
        """One pass: the host's bytes in, the answers out, time and watchdog on."""
        try:
            ready, _, _ = select.select([self.master], [], [], wait)
        except InterruptedError:
            ready = []
        if not ready:  # no EIO: the port is open (the host opened it just now if it was closed)
            self._opened()
            self.firmware.tick()
            return
        try:
            data = os.read(self.master, 4096)
        except OSError as exc:
            if exc.errno != errno.EIO:
                raise
            self._host = False  # nobody has the port open (the host closed it, or never opened it)
            self._closed_at = self.firmware.clock()
            time.sleep(wait)  # nobody has the port open: EIO until someone does
            self.firmware.tick()
            return
        self._opened()
        self.received += data
        answer = self.firmware.feed(data)
        if answer:
            os.write(self.master, answer)

    def _opened(self) -> None:
        if not self._host:
            self._host = True
            self.firmware.reset(opened_at=self._closed_at)

    def close(self) -> None:
        os.close(self.master)


def serve(device: PtyDevice, *, status_every: float = 0.0, stop: Callable[[], bool] = lambda: False) -> None:
    """Serve until `stop()` (or forever), printing the status every `status_every` s."""
    last = time.monotonic()
    while not stop():
        device.serve_once()
        if status_every > 0 and time.monotonic() - last >= status_every:
            last = time.monotonic()
            device.firmware.report(device.firmware.status())


class ServedDevice:
    """`firmware` on a new pseudo-terminal, served by a thread of this process until
    `close`: the tests and benchmarks run the whole Active path on it, the host (a
    session process, an IstBackend) opening `path`."""

    def __init__(self, firmware: Firmware) -> None:
        self.firmware = firmware
        self.pty = PtyDevice(firmware)
        self.path = self.pty.path
        self._stop = threading.Event()
        self._thread = threading.Thread(target=serve, args=(self.pty,), kwargs={"stop": self._stop.is_set},
                                        name="ist-device", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.pty.close()
