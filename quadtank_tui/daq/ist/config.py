"""The DAQ configuration of an IST rig: `protocol: ist` in a DAQ file (params/daq-ist.yaml).

    protocol: ist
    port: /dev/ttyUSB0      # the Arduino Nano's serial port
    timeout: 0.5            # s an answer may take (14 bytes at 9600 baud: 15 ms)
    open_wait: 2.0          # s after opening the port: opening it resets the Nano
    keepalive: 1.0          # s between level requests while the loop samples slower
    calibration:
      sensor_gain: 0.25     # kc, V/cm of the normalized units (the .par's Sensor)
      tank1: {dh_dr: -37.09, h0: 43.42}     # h = dh_dr r + h0, r = (Vcc - v) / v
      pump1: {c1: 39.0, c2: -0.0012, c3: 0.034, k: 3.14, u_max: 12}
    interlock: {enabled: true, limit: 0.95, tank_height: 40}
    plausible: {margin: 0.1, tank1: [-2, 45]}

Missing calibration keys take the rig's published constants (daq/ist/protocol.py).
The link is fixed by the firmware (9600 baud, 8N1); the rig is a quadruple tank
(four levels, two pumps).  Errors name the file, the line and the dotted key, as
for a Modbus configuration (the checks of daq/config_checks.py).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from quadtank_tui.daq.config import QUADTANK_CHANNELS, PlantChannels
from quadtank_tui.daq.ist import protocol as p
from quadtank_tui.daq.config_checks import PLAUSIBLE_MARGIN, Validator, config_error
from quadtank_tui.files.yamltext import key_lines, parse_yaml, read_text

PROTOCOL = "ist"
TOP_KEYS = ("protocol", "port", "timeout", "open_wait", "keepalive", "calibration", "interlock", "plausible")


@dataclass(frozen=True)
class LevelSensor:
    """h (cm) = dh_dr r + h0 of one tank's sensor."""

    dh_dr: float
    h0: float

    def level(self, r: float) -> float:
        return p.level_cm(r, self.dh_dr, self.h0)


@dataclass(frozen=True)
class IstConfig:
    """A validated IST configuration; see the module docstring."""

    port: str
    timeout: float = 0.5
    open_wait: float = 2.0
    keepalive: float = 1.0
    sensors: tuple[LevelSensor, ...] = tuple(LevelSensor(d, h) for d, h in zip(p.DH_DR, p.H0))
    pumps: tuple[p.PumpCurve, ...] = p.PUMPS
    sensor_gain: float = 0.25
    interlock_enabled: bool = True
    interlock_limit: float = 0.95
    tank_height: float = 40.0
    plausible_margin: float = PLAUSIBLE_MARGIN
    plausible: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    plant: PlantChannels = QUADTANK_CHANNELS
    source: str = field(default="<preset>", compare=False)

    def plausible_range(self, tank: int) -> tuple[float, float]:
        """(low, high) cm a level of tank 1..4 can really read; outside: a sensor fault."""
        own = self.plausible.get(f"tank{tank}")
        if own is not None:
            return own
        margin = self.plausible_margin * self.tank_height
        return (-margin, self.tank_height + margin)

    @property
    def watchdog(self) -> float:
        """The firmware's own watchdog, s: no level request for that long stops all
        four pumps (always there: a session's record says "device")."""
        return p.WATCHDOG_S

    def lock_key(self) -> str:
        """The rig's identity, the name it is locked under: its serial device with
        the links resolved (/dev/serial/by-id/... and /dev/ttyUSB0 are one rig)."""
        return f"serial:{os.path.realpath(self.port)}"

    def conversion_line(self) -> str:
        """What `daq check` says about the conversion."""
        return ("conversion: r = (Vcc - v) / v, h = dh_dr r + h0 (cm): "
                + ", ".join(f"tank{i + 1} {s.dh_dr:.4g} r + {s.h0:.4g}" for i, s in enumerate(self.sensors))
                + f"; y = {self.sensor_gain:g} h / 10")


def says_ist(text: str) -> bool:
    """Whether a DAQ file's text says `protocol: ist` (daq/open.py decides on it, once
    per file read)."""
    return any(line.split("#", 1)[0].strip().replace(" ", "") in ("protocol:ist", 'protocol:"ist"')
               for line in text.splitlines())


def load_ist_config(path: Path | str) -> IstConfig:
    """Read and validate an IST DAQ file."""
    return parse_ist_config(read_text(path, config_error), name=str(path))


def parse_ist_config(text: str, *, name: str = "<daq config>") -> IstConfig:
    node, data = parse_yaml(text, name, config_error)
    v = Validator(name, key_lines(node))
    d: dict[str, Any] = v.mapping("", data if data is not None else {}, TOP_KEYS)
    if d.get("protocol") != PROTOCOL:
        v.fail("protocol", f"must be {PROTOCOL} for this rig, got {d.get('protocol')!r}")
    port = v.require(d, "", "port")
    if not isinstance(port, str) or not port.strip():
        v.fail("port", f"must be a serial port (/dev/ttyUSB0, COM3), got {port!r}")
    timeout = v.number("timeout", d.get("timeout", 0.5), 0.0, 1.9, lo_open=True)
    open_wait = v.number("open_wait", d.get("open_wait", 2.0), 0.0, 10.0)
    keepalive = v.number("keepalive", d.get("keepalive", 1.0), 0.05, 1.5)
    cal = v.mapping("calibration", d.get("calibration", {}), ("sensor_gain", *QUADTANK_CHANNELS.tanks,
                                                              *QUADTANK_CHANNELS.pumps))
    gain = v.number("calibration.sensor_gain", cal.get("sensor_gain", 0.25), 0.0, 10.0, lo_open=True)
    sensors = []
    for i, tank in enumerate(QUADTANK_CHANNELS.tanks):
        m = v.mapping(f"calibration.{tank}", cal.get(tank, {}), ("dh_dr", "h0"))
        slope = v.number(f"calibration.{tank}.dh_dr", m.get("dh_dr", p.DH_DR[i]))
        if slope == 0.0:
            v.fail(f"calibration.{tank}.dh_dr", "must not be 0")
        sensors.append(LevelSensor(slope, v.number(f"calibration.{tank}.h0", m.get("h0", p.H0[i]))))
    pumps = []
    for i, pump in enumerate(QUADTANK_CHANNELS.pumps):
        key = f"calibration.{pump}"
        m = v.mapping(key, cal.get(pump, {}), ("c1", "c2", "c3", "k", "u_max"))
        c1 = v.number(f"{key}.c1", m.get("c1", p.PUMP_C1[i]), 0.0, lo_open=True)
        k = v.number(f"{key}.k", m.get("k", p.PUMP_K[i]), 0.0, lo_open=True)
        u_max = v.number(f"{key}.u_max", m.get("u_max", p.PUMP_U_MAX), 0.0, 24.0, lo_open=True)
        if not k * u_max < c1:
            v.fail(f"{key}.u_max", f"k u_max = {k * u_max:g} must stay below c1 = {c1:g} (the law's pole)")
        pumps.append(p.PumpCurve(c1, v.number(f"{key}.c2", m.get("c2", p.PUMP_C2[i]), -1.0, 1.0),
                                 v.number(f"{key}.c3", m.get("c3", p.PUMP_C3[i]), 0.0, 1.0), k, u_max))
    lock = v.mapping("interlock", d.get("interlock", {}), ("enabled", "limit", "tank_height"))
    enabled = lock.get("enabled", True)
    if not isinstance(enabled, bool):
        v.fail("interlock.enabled", f"must be true or false, got {enabled!r}")
    limit = v.number("interlock.limit", lock.get("limit", 0.95), 0.0, 1.0, lo_open=True)
    height = v.number("interlock.tank_height", lock.get("tank_height", 40.0), 0.0, 1000.0, lo_open=True)
    margin, plausible = v.plausible(v.mapping("plausible", d.get("plausible", {}), ("margin", *QUADTANK_CHANNELS.tanks)),
                                    QUADTANK_CHANNELS.tanks, QUADTANK_CHANNELS.unit)
    return IstConfig(port=port.strip(), timeout=timeout, open_wait=open_wait, keepalive=keepalive,
                     sensors=tuple(sensors), pumps=tuple(pumps), sensor_gain=gain, interlock_enabled=enabled,
                     interlock_limit=limit, tank_height=height, plausible_margin=margin, plausible=plausible,
                     source=name)
