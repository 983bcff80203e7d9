"""The virtual rig: the nonlinear quadruple-tank model served over Modbus TCP (B11).

It stands where the lab's DAQ would: its input registers carry the sensor voltages
of the simulated tanks (kc * h, plus optional noise, offset and quantization), its
output registers drive the simulated pumps, and the process advances in wall-clock
time (times a speed factor), whatever the client does.  Like the device its map
describes it has that device's watchdog (daq/rig_watchdog.py: the LabJack's
WATCHDOG_* registers), off until a program arms it: then a silence of its timeout
sets the pumps (and their registers) to what the program said, so a program that
dies or stops cannot leave the pumps running.  A map with `watchdog: none` is a
device without one.

The register layout and the wiring are those of a DAQ configuration (`--map`, the
LabJack preset by default), read for the plant it serves: a two-tank plant serves
two level inputs and one pump output per pump (the registers of the channels it
does not have do not exist), so `quadtank --daq params/virtual-rig.yaml` reaches it
exactly as it would reach the hardware.  Time is injected (`clock`), so the
model-side behaviour is testable without sleeping.  It says what it is: a block of
registers with its pump amplifiers and sensors (daq/identity.py) that `daq check`
and the start of Active control compare with the program's DAQ file.
"""

from __future__ import annotations

import asyncio
import math
import random
import signal
import sys
import time
from dataclasses import dataclass
from typing import Callable, Sequence, TextIO

from quadtank_tui.core import faults as fx
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.plants.johansson import PlantParams
from quadtank_tui.core.plants import Plant, QuadTank
from quadtank_tui.daq.config import DaqConfig
from quadtank_tui.daq.identity import RigIdentity
from quadtank_tui.daq.registers import decode, encode
from quadtank_tui.daq.rig_watchdog import RigWatchdog
from quadtank_tui.daq.server import IllegalAddress, ModbusTcpServer

#: The pumps take 0..10 V; an analog input reads at most about +-10.5 V.
PUMP_RANGE = (0.0, FULL_SCALE_V)
AIN_RANGE = (-10.5, 10.5)
#: How often (wall s) the rig advances without being asked, so the watchdog and the
#: water keep time even when nobody reads.
TICK_S = 0.05


@dataclass(frozen=True)
class SensorModel:
    """What the rig's level sensors add to kc * h: V = kc h + offset + N(0, noise),
    rounded to a multiple of `lsb` (0: none)."""

    noise: float = 0.0
    offset: float = 0.0
    lsb: float = 0.0
    seed: int = 0


class VirtualRig:
    """The register bank the server serves: model state, pumps, watchdog."""

    def __init__(
        self,
        config: DaqConfig,
        plant: PlantParams | Plant,
        levels_cm: Sequence[float],
        *,
        speed: float = 1.0,
        watchdog: float = 0.0,
        sensors: SensorModel = SensorModel(),
        clock: Callable[[], float] = time.monotonic,
        report: Callable[[str], None] = lambda text: None,
    ) -> None:
        if not speed > 0 or not math.isfinite(speed):
            raise ValueError(f"speed must be a number > 0, got {speed}")
        if watchdog < 0 or not math.isfinite(watchdog):
            raise ValueError(f"watchdog must be >= 0 s (0: off until a program arms it), got {watchdog}")
        if watchdog > 0 and config.watchdog is None:
            raise ValueError(f"watchdog: the map {config.source} declares none (watchdog: none)")
        self.config = config
        #: The process through the plant interface; `plant` stays the quadruple tank's
        #: constants (None for another plant: core.plants).
        self.process: Plant = QuadTank(plant) if isinstance(plant, PlantParams) else plant
        config.check_plant(self.process)  # DaqConfigError: the map is another plant's
        self.plant = self.process.params if isinstance(self.process, QuadTank) else None
        #: Faults injected at the rig (`quadtank rig --fault`): the Active path sees them.
        self.faults = fx.Faults()
        self.h = tuple(float(x) for x in levels_cm)
        self.speed = speed
        #: the device's watchdog (None: the map declares none); `watchdog` > 0 starts it armed
        self.watchdog = None if config.watchdog is None else RigWatchdog(
            config.watchdog, {o: config.stop_volts(o) for o in config.outputs}, watchdog)
        self.sensors = sensors
        self.clock = clock
        self.report = report
        self._rng = random.Random(sensors.seed)
        self._tanks = [config.tank_register(i) for i in range(1, len(config.tanks) + 1)]
        self._outputs = [config.pump_output(i).register for i in range(1, len(config.pump_channels) + 1)]
        self._out_words: dict[int, int] = {}
        self._identity_words = self.identity().words()
        self._stop_pumps()  # pumps and their registers at 0
        self._now = clock()
        self.t = 0.0                      # process time, s
        self.last_request = self._now     # wall time of the last request (any client)
        self.watchdog_trips = 0

    # --- time -------------------------------------------------------------------------

    def tick(self) -> None:
        """Bring the process up to the clock (and apply the watchdog on the way)."""
        now = self.clock()
        wd = self.watchdog
        if wd is not None and wd.enabled and wd.timeout > 0:
            deadline = self.last_request + wd.timeout
            if deadline <= now:  # (it would fire again after each further timeout: the same values)
                self._advance_to(max(deadline, self._now))
                self.last_request = now
                self._fire(wd)
        self._advance_to(now)

    def _fire(self, wd: RigWatchdog) -> None:
        before = self.pump_volts
        set_to = wd.actions()
        for name, volts in set_to:
            reg = self.config.outputs[name].register
            self._out_words.update((a, w) for a, w in zip(reg.span, encode(reg, volts)) if a in self._out_words)
        self._pumps_from_words()
        if self.pump_volts != before:
            self.watchdog_trips += 1
            said = ", ".join(f"{n} set to {v:g} V" for n, v in set_to)
            self.report(f"watchdog: no request for {wd.timeout:g} s, {said}")

    def _advance_to(self, wall: float) -> None:
        if wall <= self._now:
            return
        dt = (wall - self._now) * self.speed
        # the DAQ's 0..10 V drive the plant's amplifiers over their range (x 1.0 on the
        # quadruple tank's 10 V ones: the volts as they are); the plant's own step
        # (with its effects) whenever no fault acts (core.faults.advance)
        v = [x * (s.full_scale / FULL_SCALE_V) for x, s in zip(self.pump_volts, self.process.inputs)]
        self.h = fx.advance(self.process, self.faults, self.h, v, dt)
        self.t += dt
        self._now = wall

    def _stop_pumps(self) -> None:
        self.pump_volts: tuple[float, ...] = tuple(0.0 for _ in self._outputs)
        for reg in self._outputs:
            self._out_words.update(zip(reg.span, encode(reg, 0.0)))

    # --- the registers ----------------------------------------------------------------

    def sensor_volts(self) -> tuple[float, ...]:
        """One reading of the plant's sensors (tanks 1..N), noise drawn afresh."""
        s = self.sensors
        out = []
        true = list(self.process.output(self.h))
        if self.faults:
            gauss = [self._rng.gauss(0.0, 1.0) for _ in true]
            true = [10.0 * y for y in fx.measure([v / 10.0 for v in true], self.faults, self.t, gauss)]
        for v in true:
            v += s.offset
            if s.noise > 0:
                v += self._rng.gauss(0.0, s.noise)
            if s.lsb > 0:
                v = round(v / s.lsb) * s.lsb
            out.append(min(AIN_RANGE[1], max(AIN_RANGE[0], v)))
        return tuple(out)

    def identity(self) -> RigIdentity:
        """What this rig is (daq/identity.py): the pump calibration it applies to the
        DAC volts (its map's), its sensors' level per volt (1 / kc of each tank) and
        offset, the pumps' range."""
        n = len(self.process.states)
        kc = [self.process.output([1.0 if j == i else 0.0 for j in range(n)])[i] for i in range(n)]
        tanks = range(len(self._tanks))
        return RigIdentity(tuple(p.gain for p in self.config.pumps), tuple(p.offset for p in self.config.pumps),
                           tuple(1.0 / kc[i] for i in tanks), tuple(-self.sensors.offset / kc[i] for i in tanks),
                           tuple(PUMP_RANGE[1] for _ in self.config.pumps))

    def read(self, address: int, count: int) -> list[int]:
        self.tick()
        self._heard()
        words = dict(self._out_words)
        words.update(self._identity_words)
        if self.watchdog is not None:
            words.update(self.watchdog.words())
        asked = range(address, address + count)
        if any(a in asked for reg in self._tanks for a in reg.span):  # a noise draw per sensor read only
            for reg, v in zip(self._tanks, self.sensor_volts()):
                words.update(zip(reg.span, encode(reg, v)))
        try:
            return [words[a] for a in range(address, address + count)]
        except KeyError as exc:
            raise IllegalAddress(f"no register {exc.args[0]}") from None

    def write(self, address: int, values: Sequence[int]) -> None:
        span = range(address, address + len(values))
        wd = self.watchdog
        setting = [wd is not None and wd.owns(a) for a in span]
        if any(a not in self._out_words and not own for a, own in zip(span, setting)):
            raise IllegalAddress(f"registers {address}..{span[-1]} are not all outputs")
        self.tick()
        self._heard()
        if wd is not None and any(setting):
            was_on = wd.enabled
            own_span = [a for a, own in zip(span, setting) if own]
            own_values = [v for v, own in zip(values, setting) if own]
            if wd.strict and wd.clears(own_span, own_values):
                self.last_request = self._now  # the feed with the key: a strict watchdog's only clear
            wd.write(own_span, own_values)
            if wd.enabled and not was_on:
                self.last_request = self._now  # armed now: its timer starts from 0
        self._out_words.update((a, v) for a, v, own in zip(span, values, setting) if not own)
        self._pumps_from_words()

    def _heard(self) -> None:
        """A request: it clears the watchdog's timer unless the watchdog is strict."""
        if self.watchdog is None or not (self.watchdog.enabled and self.watchdog.strict):
            self.last_request = self._now

    def _pumps_from_words(self) -> None:
        volts = []
        for i, reg in enumerate(self._outputs):
            dac = decode(reg, [self._out_words[a] for a in reg.span])
            pump = self.config.pumps[i].level(dac) if math.isfinite(dac) else 0.0
            volts.append(min(PUMP_RANGE[1], max(PUMP_RANGE[0], pump)))
        self.pump_volts = tuple(volts)

    def set_fault(self, fault: fx.Fault) -> fx.Fault:
        """Switch a fault on now (FaultError if the plant cannot have it)."""
        reading = [v / 10.0 for v in self.process.output(self.h)]
        began = fx.switched(fault, self.process, self.t, reading)
        self.faults = self.faults.on(began)
        return began

    def status(self) -> str:
        """One line for the rig's console."""
        h = " ".join(f"{x:5.3g}" if self.plant is None else f"{x:5.2f}" for x in self.h)
        unit = self.process.states[0].unit
        faults = f"  faults: {self.faults.labels()}" if self.faults else ""
        pumps = " ".join(f"{v:.2f}" for v in self.pump_volts)
        return f"t={self.t:8.1f} s  h=[{h}] {unit}  pumps=[{pumps}] V{faults}"


# --- running it ------------------------------------------------------------------------

def describe(config: DaqConfig) -> str:
    """The wiring the rig serves, e.g. "tank1=AIN0@input:0 ... pump2=DAC1@holding:1002"."""
    parts = [f"{t}={config.channels[t]}@{config.tank_register(i + 1).address}" for i, t in enumerate(config.tanks)]
    parts += [f"{p}={config.channels[p]}@{config.pump_output(i + 1).register.address}"
              for i, p in enumerate(config.pump_channels)]
    return " ".join(parts)


async def serve_rig(
    rig: VirtualRig,
    host: str,
    port: int,
    *,
    reply_delay: float = 0.0,
    status_every: float = 0.0,
    out: TextIO = sys.stdout,
    stop: asyncio.Event | None = None,
) -> None:
    """Serve `rig` until `stop` is set (or SIGINT/SIGTERM)."""
    server = ModbusTcpServer(rig, reply_delay=reply_delay)
    bound_host, bound_port = await server.start(host, port)
    print(f"quadtank rig: serving on {bound_host}:{bound_port} "
          f"(speed x{rig.speed:g}, {rig.watchdog.status() if rig.watchdog else 'no watchdog'}, "
          f"noise {rig.sensors.noise:g} V; "
          f"{describe(rig.config)})", file=out, flush=True)
    stop = stop or asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            loop.add_signal_handler(sig, stop.set)
        except (NotImplementedError, RuntimeError):  # not the main thread / platform
            pass
    last_status = time.monotonic()
    try:
        while not stop.is_set():
            rig.tick()
            if status_every > 0 and time.monotonic() - last_status >= status_every:
                last_status = time.monotonic()
                print(rig.status(), file=out, flush=True)
            try:
                await asyncio.wait_for(stop.wait(), TICK_S)
            except asyncio.TimeoutError:
                pass
    finally:
        await server.stop()
        print("quadtank rig: stopped", file=out, flush=True)
