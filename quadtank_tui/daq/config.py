"""The DAQ configuration: how the program reaches the rig's converter over Modbus TCP.

One YAML file (examples: `params/daq-labjack.yaml`, `params/virtual-rig.yaml`) says

- the link: `host`, `port`, `device_id`, `timeout` (s per request; one retry);
- the register map: four analog inputs and two outputs by name, each an address in
  the input or holding table, FLOAT32 (with word order) or a scaled 16-bit integer;
- the channel map: which input carries which tank and which output drives which
  pump (the original's Table 1, Nunes 1998 appendix A.2: in 0..3 = tanks 1..4,
  out 0/1 = pumps 1/2);
- the calibration: level (cm) = gain * volts + offset per tank (Desautel 2.3; fit
  with `quadtank_tui.core.calibration.fits.fit_sensor`) and the sensor gain kc (V/cm) the
  normalized units assume; per pump, pump volts = gain * output volts + offset
  (an amplifier between a 0-5 V DAC and a 0-10 V pump is gain 2);
- output limits (volts the output may be written, the device's safe range);
- the high-level interlock (fraction of the tank height, default 0.95);
- the plausible range of each tank's level (cm): a reading outside it is a sensor
  fault (a broken wire reads the rail, -10.5 V), not a level; by default the tank
  from `margin` x its height below the bottom to as much above the top;
- the device's own watchdog (`watchdog:`, daq/watchdog.py), or `watchdog: none` for
  a device without one (said so at start, in `daq check` and `quadtank sessions`).

The channels follow the plant in use (:class:`PlantChannels`, from the `.par`'s
PLANT section; the quadruple tank without one): one level channel per tank
(tank1..tankN) and one pump channel per pump (pump1..pumpM), so a two-tank rig has
tank1, tank2 and no tank3/tank4.  The preset's channels beyond the plant's are
dropped; a file that names a channel the plant does not have (or leaves one out,
with `preset: none`) is refused with the extra or missing keys listed.  For a plant
other than the quadruple tank the preset's sensor calibration gives way to the
plant's own sensor gains (kc1, kc2 of the cascade, Gd of the two-input rig) and
tank height, in the plant's length unit.

Every file starts from a preset (`preset: labjack`, the default; `preset: none` for
a complete file of your own) and overrides keys.  Unknown keys, wrong types and
out-of-range values are refused with the file, the line and the dotted key, so a
typo never silently leaves a default in force.
"""

from __future__ import annotations

import copy
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping


from quadtank_tui.core.calibration.fits import SensorCalibration
from quadtank_tui.daq.interlock import QUADTANK_FEEDERS
from quadtank_tui.daq.registers import MAX_ADDRESS, SETTING_TYPES, TABLES, TYPES, WORD_ORDERS, Register
from quadtank_tui.daq.config_checks import PLAUSIBLE_MARGIN, DaqConfigError, Validator, config_error, show
from quadtank_tui.daq.watchdog import OutputAction, Watchdog
from quadtank_tui.files.yamltext import key_lines, parse_yaml, read_text

if TYPE_CHECKING:  # core.plants loads numpy; reading a configuration does not need it
    from quadtank_tui.core.plants import Plant

#: The channel names of the quadruple tank, the largest plant (four levels, two pumps).
TANKS = ("tank1", "tank2", "tank3", "tank4")
PUMPS = ("pump1", "pump2")
#: A key naming a level or pump channel (tank7 too: it is refused as extra, not unknown).
CHANNEL_KEY = re.compile(r"(tank|pump)\d+")

#: LabJack T-series (T4/T7/T8) Modbus map, zero-based, big-endian, one overlapping
#: map served on function codes 3 and 4: AIN#(0:13) from address 0 and DAC#(0:1) from
#: 1000, FLOAT32 (2 registers) each; DACs read/write, 0-5 V.  Wired as Table 1.
LABJACK: dict[str, Any] = {
    "host": "192.168.1.207",
    "port": 502,
    "device_id": 1,
    "timeout": 0.5,
    "inputs": {
        f"AIN{i}": {"table": "input", "address": 2 * i, "type": "float32", "word_order": "big"}
        for i in range(4)
    },
    "outputs": {
        f"DAC{i}": {"table": "holding", "address": 1000 + 2 * i, "type": "float32",
                    "word_order": "big", "limits": [0.0, 5.0]}
        for i in range(2)
    },
    "channels": {"tank1": "AIN0", "tank2": "AIN1", "tank3": "AIN2", "tank4": "AIN3",
                 "pump1": "DAC0", "pump2": "DAC1"},
    "calibration": {
        "sensor_gain": 0.5,
        **{t: {"gain": 2.0, "offset": 0.0} for t in TANKS},
        **{p: {"gain": 1.0, "offset": 0.0} for p in PUMPS},
    },
    "interlock": {"enabled": True, "limit": 0.95, "tank_height": 20.0},
    # The T-series watchdog (T-Series Datasheet 23.0, Modbus map; UINT32 unless
    # said): WATCHDOG_ENABLE_DEFAULT 61600, WATCHDOG_TIMEOUT_S_DEFAULT 61604 (whole
    # seconds), WATCHDOG_STRICT_CLEAR 61614 (any write clears it while strict mode
    # is off), WATCHDOG_DAC0_ENABLE_DEFAULT 61640, WATCHDOG_DAC0_DEFAULT 61642
    # (FLOAT32 volts), WATCHDOG_DAC1_ENABLE_DEFAULT 61650, WATCHDOG_DAC1_DEFAULT 61652,
    # WATCHDOG_STRICT_ENABLE_DEFAULT 61610, WATCHDOG_STRICT_KEY_DEFAULT 61612 (LJM's
    # LabJackMModbusMap.h / ljm_constants.json): armed strict with a key per run, only
    # our feed clears it - not another client's reads.  The settings are power-up
    # defaults (flash): only those that differ are written (the key, once a run).
    "watchdog": {
        "timeout": "auto",
        "enable": {"address": 61600, "type": "uint32"},
        "timeout_register": {"address": 61604, "type": "uint32"},
        "feed": {"address": 61614, "type": "uint32"},
        "strict_enable": {"address": 61610, "type": "uint32"},
        "strict_key": {"address": 61612, "type": "uint32"},
        "outputs": {
            f"DAC{i}": {"enable": {"address": 61640 + 10 * i, "type": "uint32"},
                        "value": {"address": 61642 + 10 * i, "type": "float32"}}
            for i in range(2)
        },
    },
}

PRESETS: dict[str, dict[str, Any]] = {"labjack": LABJACK}


@dataclass(frozen=True)
class PlantChannels:
    """What a DAQ configuration wires for one plant: its level channels
    (tank1..tankN), its pump channels (pump1..pumpM), and, for a plant other than
    the quadruple tank, the defaults its sensors and tanks give (per tank sensor
    gain, V per level unit; the tank height; the length unit)."""

    kind: str
    title: str
    tanks: tuple[str, ...]
    pumps: tuple[str, ...]
    sensor_gains: tuple[float, ...]
    height: float
    unit: str
    #: per tank, the pumps (0-based) the interlock cuts when it is overfull
    feeders: tuple[tuple[int, ...], ...] = QUADTANK_FEEDERS

    @classmethod
    def of(cls, plant: Plant) -> PlantChannels:
        n = len(plant.states)
        gains = tuple(plant.output([1.0 if j == i else 0.0 for j in range(n)])[i] for i in range(n))
        return cls(kind=plant.kind, title=plant.title, tanks=tuple(f"tank{i + 1}" for i in range(n)),
                   pumps=tuple(f"pump{i + 1}" for i in range(len(plant.inputs))),
                   sensor_gains=gains, height=max(s.hi for s in plant.states), unit=plant.states[0].unit,
                   feeders=_feeders(plant))

    @property
    def keeps_preset(self) -> bool:
        """The quadruple tank keeps the preset's calibration and height as they were."""
        return self.kind == "quadtank"

    def describe(self) -> str:
        """e.g. "a coupled-cascade plant has 2 level channels (tank1, tank2) and 1 pump channel (pump1)"."""
        def count(names: tuple[str, ...], what: str) -> str:
            return f"{len(names)} {what} channel{'s' if len(names) != 1 else ''} ({', '.join(names)})"
        return f"a {self.kind} plant has {count(self.tanks, 'level')} and {count(self.pumps, 'pump')}"


def _feeders(plant: Plant) -> tuple[tuple[int, ...], ...]:
    """Per tank, the pumps pouring into it; for a tank no pump pours into, those of
    the tanks draining into it (the lower tank of the cascade: the one pump)."""
    lay = plant.layout()
    direct = [sorted({p.input for p in lay.pumps for tank, _ in p.feeds if tank == i})
              for i in range(len(plant.states))]
    out = []
    for i, pumps in enumerate(direct):
        if not pumps:
            pumps = sorted({p for pipe in lay.pipes if pipe.target == i for p in direct[pipe.source]})
        out.append(tuple(pumps))
    return tuple(out)


#: The quadruple tank's channels: what a configuration wires when no plant is given
#: (the sensor gain and height are the preset's; the quadruple tank keeps them).
QUADTANK_CHANNELS = PlantChannels("quadtank", "quadruple tank (Johansson)", TANKS, PUMPS, (0.5,) * 4, 20.0, "cm")

@dataclass(frozen=True)
class Output:
    """An analog output: its register and the volts it may be written (lo, hi)."""

    register: Register
    limits: tuple[float, float]


@dataclass(frozen=True)
class DaqConfig:
    """A validated configuration; see the module docstring for the meaning."""

    host: str
    port: int
    device_id: int
    timeout: float
    inputs: Mapping[str, Register]
    outputs: Mapping[str, Output]
    #: tank1..tankN -> input name; pump1..pumpM -> output name (the plant's channels)
    channels: Mapping[str, str]
    #: per tank: level (cm) from volts
    sensors: tuple[SensorCalibration, ...]
    #: per pump: pump volts from output volts
    pumps: tuple[SensorCalibration, ...]
    #: kc (V/cm) of the normalized units: y = sensor_gain * level / 10
    sensor_gain: float = 0.5
    #: the plant these channels are wired for
    plant: PlantChannels = QUADTANK_CHANNELS
    #: kc of each tank (all sensor_gain unless the plant's or the file's differ)
    sensor_gains: tuple[float, ...] = ()
    interlock_enabled: bool = True
    interlock_limit: float = 0.95
    tank_height: float = 20.0
    #: fraction of tank_height below 0 and above the top of the default plausible range
    plausible_margin: float = PLAUSIBLE_MARGIN
    #: tank1..tank4 -> (low, high) cm, where the file gives a range of its own
    plausible: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    #: the device's own watchdog (None: the device has none, `watchdog: none`)
    watchdog: Watchdog | None = None
    source: str = field(default="<preset>", compare=False)

    def __post_init__(self) -> None:
        if not self.sensor_gains:
            object.__setattr__(self, "sensor_gains", (self.sensor_gain,) * len(self.plant.tanks))

    @property
    def tanks(self) -> tuple[str, ...]:
        """The level channels wired (tank1..tankN of the plant)."""
        return self.plant.tanks

    @property
    def pump_channels(self) -> tuple[str, ...]:
        """The pump channels wired (pump1..pumpM of the plant)."""
        return self.plant.pumps

    def tank_register(self, tank: int) -> Register:
        """The input register of tank 1..N."""
        return self.inputs[self.channels[self.tanks[tank - 1]]]

    def plausible_range(self, tank: int) -> tuple[float, float]:
        """(low, high) cm a level of tank 1..N can really read; outside: a sensor fault."""
        own = self.plausible.get(self.tanks[tank - 1])
        if own is not None:
            return own
        margin = self.plausible_margin * self.tank_height
        return (-margin, self.tank_height + margin)

    def pump_output(self, pump: int) -> Output:
        """The output of pump 1..M."""
        return self.outputs[self.channels[self.pump_channels[pump - 1]]]

    def stop_volts(self, output: str) -> float:
        """The volts written to `output` to stop its pump (a pump's calibration
        offset may make it other than 0 V), within the output's limits."""
        lo, hi = self.outputs[output].limits
        for i, pump in enumerate(self.pump_channels):
            if self.channels[pump] == output:
                return min(hi, max(lo, self.pumps[i].volts(0.0)))
        return min(hi, max(lo, 0.0))

    def watchdog_line(self) -> str:
        """What `daq check` and a run's start say about the device's watchdog."""
        if self.watchdog is None:
            return (f"watchdog: none declared by {self.source}: if this program dies its guard stops the "
                    "pumps; if the computer dies or hangs, nothing does")
        return f"watchdog: {self.watchdog.describe()}"

    def check_plant(self, plant: Plant) -> None:
        """DaqConfigError unless these channels are wired for `plant`'s kind (the
        configuration was read for another plant than the one now in use)."""
        if plant.kind != self.plant.kind:
            wanted = PlantChannels.of(plant)
            raise DaqConfigError(self.source, f"wired for the {self.plant.kind} plant, but the plant in use is "
                                 f"{plant.kind}: {wanted.describe()}; read the configuration for it")


# --- reading -------------------------------------------------------------------------

def load_daq_config(path: Path | str, plant: Plant | None = None) -> DaqConfig:
    """Read and validate a DAQ configuration file, or a preset name (`labjack`), for
    the channels of `plant` (the quadruple tank when None)."""
    text_path = str(path)
    if text_path in PRESETS:
        return parse_daq_config(f"preset: {json.dumps(text_path)}\n", name=f"preset {text_path}", plant=plant)
    return parse_daq_config(read_text(path, config_error), name=text_path, plant=plant)


def parse_daq_config(text: str, *, name: str = "<daq config>", plant: Plant | None = None) -> DaqConfig:
    """Validate the YAML `text` (named `name` in errors) over its preset, for the
    channels of `plant` (the quadruple tank when None)."""
    wiring = QUADTANK_CHANNELS if plant is None else PlantChannels.of(plant)
    node, data = parse_yaml(text, name, config_error)
    lines = key_lines(node)
    v = _MapValidator(name, lines, wiring)
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise DaqConfigError(name, "must be a mapping of keys (host: ..., port: ...)", line=1)
    preset_name = data.get("preset", "labjack")
    if preset_name is not None and not isinstance(preset_name, str):
        v.fail("preset", f"must be a preset name ({', '.join([*PRESETS, 'none'])}), got {show(preset_name)}")
    if preset_name in (None, "none"):
        base: dict[str, Any] = {}
    elif preset_name in PRESETS:
        base = copy.deepcopy(PRESETS[preset_name])
    else:
        v.fail("preset", f"unknown preset {preset_name!r}; known: {', '.join([*PRESETS, 'none'])}")
    v.no_extra_channels(data)
    merged = _merge(_for_plant(base, wiring), {k: val for k, val in data.items() if k != "preset"})
    return v.config(merged)


def _for_plant(preset: dict[str, Any], wiring: PlantChannels) -> dict[str, Any]:
    """The preset's mapping with only the plant's channels; for another plant than
    the quadruple tank its sensor calibration and tank height give way to the
    plant's (ideal sensors: level = volts / kc_i)."""
    out = copy.deepcopy(preset)
    names = set(wiring.tanks + wiring.pumps)
    for section in ("channels", "calibration", "plausible"):
        if isinstance(out.get(section), dict):
            out[section] = {k: val for k, val in out[section].items()
                            if not CHANNEL_KEY.fullmatch(str(k)) or k in names}
    if wiring.keeps_preset:
        return out
    cal = out.get("calibration")
    if isinstance(cal, dict):
        cal.pop("sensor_gain", None)
        for tank in wiring.tanks:
            cal.pop(tank, None)
    lock = out.get("interlock")
    if isinstance(lock, dict):
        lock.pop("tank_height", None)
    return out


def _merge(base: dict[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    """`over` on top of `base`, mappings merged key by key (a map replaces a map's
    keys, so `inputs: {AIN0: {address: 8}}` changes one address of the preset).
    A whole register table given in the file replaces the preset's names only when
    it names none of them (a PLC map with names of its own)."""
    out = dict(base)
    for k, val in over.items():
        if isinstance(val, dict) and isinstance(out.get(k), dict):
            if k in ("inputs", "outputs") and not set(val) & set(out[k]):
                out[k] = val
            else:
                out[k] = _merge(out[k], val)
        else:
            out[k] = val
    return out


class _MapValidator(Validator):
    """Turns the merged mapping into a DaqConfig, failing with file, line and key."""

    def __init__(self, name: str, lines: Mapping[str, int], wiring: PlantChannels = QUADTANK_CHANNELS) -> None:
        super().__init__(name, lines)
        self.wiring = wiring

    def no_extra_channels(self, data: Mapping[str, Any]) -> None:
        """The file's own channel keys (channels, calibration, plausible) the plant
        does not have: refused, all of them named (a 4-level map for a 2-tank plant)."""
        names = set(self.wiring.tanks + self.wiring.pumps)
        for section in ("channels", "calibration", "plausible"):
            m = data.get(section)
            if not isinstance(m, dict):
                continue
            extra = [str(k) for k in m if CHANNEL_KEY.fullmatch(str(k)) and k not in names]
            if extra:
                are = "is extra" if len(extra) == 1 else "are extra"
                self.fail(f"{section}.{extra[0]}", f"{', '.join(extra)} {are}: {self.wiring.describe()}")

    def require_channels(self, m: Mapping[str, Any]) -> None:
        """Every channel of the plant wired; the missing ones named together."""
        missing = [ch for ch in self.wiring.tanks + self.wiring.pumps if ch not in m]
        if missing:
            self.fail(f"channels.{missing[0]}", f"{', '.join(missing)} missing: {self.wiring.describe()}")

    def register(self, key: str, value: Any, *, output: bool) -> tuple[Register, dict[str, Any]]:
        allowed = ("table", "address", "type", "word_order", "scale") + (("limits",) if output else ())
        m = self.mapping(key, value, allowed)
        table = self.choice(f"{key}.table", m.get("table", "holding" if output else "input"), TABLES)
        if output and table != "holding":
            self.fail(f"{key}.table", "an output must be a holding register (inputs cannot be written)")
        reg_type = self.choice(f"{key}.type", m.get("type", "float32"), TYPES)
        address = self.integer(f"{key}.address", self.require(m, key, "address"), 0,
                               MAX_ADDRESS - (1 if reg_type == "float32" else 0))
        word_order = self.choice(f"{key}.word_order", m.get("word_order", "big"), WORD_ORDERS)
        scale = 1.0
        if reg_type != "float32":
            scale = self.number(f"{key}.scale", self.require(m, key, "scale"), 0.0, lo_open=True)
        return Register(table, address, reg_type, word_order, scale), m  # type: ignore[arg-type]

    def calibration(self, key: str, value: Any) -> SensorCalibration:
        m = self.mapping(key, value, ("gain", "offset"))
        gain = self.number(f"{key}.gain", self.require(m, key, "gain"))
        if gain == 0.0:
            self.fail(f"{key}.gain", "must not be 0")
        offset = self.number(f"{key}.offset", m.get("offset", 0.0))
        return SensorCalibration(gain=gain, offset=offset)

    def config(self, d: dict[str, Any]) -> DaqConfig:
        top = ("host", "port", "device_id", "timeout", "inputs", "outputs", "channels",
               "calibration", "interlock", "plausible", "watchdog")
        self.mapping("", d, top)
        host = self.require(d, "", "host")
        if not isinstance(host, str) or not host.strip():
            self.fail("host", f"must be a host name or address, got {show(host)}")
        port = self.integer("port", self.require(d, "", "port"), 1, 65535)
        device_id = self.integer("device_id", d.get("device_id", 1), 0, 255)
        timeout = self.number("timeout", d.get("timeout", 0.5), 0.0, 10.0, lo_open=True)
        inputs = {n: self.register(f"inputs.{n}", r, output=False)[0]
                  for n, r in self.mapping("inputs", self.require(d, "", "inputs")).items()}
        outputs: dict[str, Output] = {}
        for n, r in self.mapping("outputs", self.require(d, "", "outputs")).items():
            reg, m = self.register(f"outputs.{n}", r, output=True)
            outputs[n] = Output(reg, self.limits(f"outputs.{n}.limits", m.get("limits", [0.0, 10.0])))
        tanks, pump_names = self.wiring.tanks, self.wiring.pumps
        wired = self.mapping("channels", self.require(d, "", "channels"), tanks + pump_names)
        self.require_channels(wired)
        channels = self._channels(wired, inputs, outputs)
        cal = self.mapping("calibration", d.get("calibration", {}), ("sensor_gain",) + tanks + pump_names)
        gains = self.sensor_gains(cal)
        sensors = tuple(self.calibration(f"calibration.{t}", cal.get(t, {"gain": 1.0 / kc}))
                        for t, kc in zip(tanks, gains))
        pumps = tuple(self.calibration(f"calibration.{p}", cal.get(p, {"gain": 1.0})) for p in pump_names)
        lock = self.mapping("interlock", d.get("interlock", {}), ("enabled", "limit", "tank_height"))
        enabled = lock.get("enabled", True)
        if not isinstance(enabled, bool):
            self.fail("interlock.enabled", f"must be true or false, got {show(enabled)}")
        limit = self.number("interlock.limit", lock.get("limit", 0.95), 0.0, 1.0, lo_open=True)
        default_height = 20.0 if self.wiring.keeps_preset else self.wiring.height
        height = self.number("interlock.tank_height", lock.get("tank_height", default_height), 0.0, 1000.0,
                             lo_open=True)
        margin, plausible = self.plausible(self.mapping("plausible", d.get("plausible", {}), ("margin",) + tanks),
                                           tanks, self.wiring.unit)
        watchdog = self.watchdog(d.get("watchdog"), outputs, [channels[p] for p in pump_names])
        self._no_overlap(inputs, outputs, watchdog)
        return DaqConfig(
            host=host.strip(), port=port, device_id=device_id, timeout=timeout,
            inputs=inputs, outputs=outputs, channels=channels,
            sensors=sensors, pumps=pumps, sensor_gain=gains[0], plant=self.wiring, sensor_gains=gains,
            interlock_enabled=enabled, interlock_limit=limit,
            tank_height=height, plausible_margin=margin, plausible=plausible, watchdog=watchdog,
            source=self.name,
        )

    def sensor_gains(self, cal: Mapping[str, Any]) -> tuple[float, ...]:
        """kc of each tank: `sensor_gain` a number (every tank) or a list (one per
        tank); by default 0.5 V/cm for the quadruple tank, the plant's own otherwise."""
        key = "calibration.sensor_gain"
        n = len(self.wiring.tanks)
        value = cal.get("sensor_gain", 0.5 if self.wiring.keeps_preset else list(self.wiring.sensor_gains))
        if isinstance(value, list):
            if len(value) != n:
                self.fail(key, f"must be one number or a list of {n} (one per level channel), got {show(value)}")
            return tuple(self.number(f"{key}.{i}", x, 0.0, 1000.0, lo_open=True) for i, x in enumerate(value))
        return (self.number(key, value, 0.0, 10.0 if self.wiring.keeps_preset else 1000.0, lo_open=True),) * n

    def _channels(self, m: Mapping[str, Any], inputs: Mapping[str, Register],
                  outputs: Mapping[str, Output]) -> dict[str, str]:
        out: dict[str, str] = {}
        for names, table, kind in ((self.wiring.tanks, inputs, "inputs"), (self.wiring.pumps, outputs, "outputs")):
            seen: dict[str, str] = {}
            for ch in names:
                ref = self.require(m, "channels", ch)
                if not isinstance(ref, str) or ref not in table:
                    self.fail(f"channels.{ch}", f"{show(ref)} is not one of the {kind} ({', '.join(table)})")
                if ref in seen:
                    self.fail(f"channels.{ch}", f"{ref} is already wired to {seen[ref]}")
                seen[ref] = ch
                out[ch] = ref
        return out

    def watchdog(self, value: Any, outputs: Mapping[str, Output], pump_outputs: list[str]) -> Watchdog | None:
        """`watchdog:` - the device's own, or None for `watchdog: none` (or absent
        from a complete file).  Every pump output must be set by it on a timeout."""
        if value is None or value == "none":
            return None
        if not isinstance(value, dict):
            self.fail("watchdog", f"must be the device's watchdog registers (a mapping) or none, got {show(value)}")
        m = self.mapping("watchdog", value, ("timeout", "enable", "timeout_register", "feed", "outputs",
                                             "strict_enable", "strict_key"))
        least = m.get("timeout", "auto")
        timeout = 0.0 if least == "auto" else self.number("watchdog.timeout", least, 0.0, 3600.0, lo_open=True)
        actions = []
        for name, spec in self.mapping("watchdog.outputs", self.require(m, "watchdog", "outputs")).items():
            key = f"watchdog.outputs.{name}"
            if name not in outputs:
                self.fail(key, f"{name} is not one of the outputs ({', '.join(outputs)})")
            a = self.mapping(key, spec, ("value", "enable"))
            enable = self.setting(f"{key}.enable", a["enable"]) if "enable" in a else None
            actions.append(OutputAction(name, self.setting(f"{key}.value", self.require(a, key, "value"),
                                                           "float32"), enable))
        missing = [o for o in pump_outputs if o not in {a.output for a in actions}]
        if missing:
            self.fail("watchdog.outputs", f"{', '.join(missing)} missing: the watchdog must stop every pump")
        strict = {k: self.setting(f"watchdog.{k}", m[k]) if m.get(k) is not None else None
                  for k in ("strict_enable", "strict_key")}
        if (strict["strict_enable"] is None) != (strict["strict_key"] is None) or \
                (strict["strict_enable"] is not None and m.get("feed") is None):
            self.fail("watchdog.strict_enable", "strict mode needs strict_enable, strict_key and feed together")
        return Watchdog(
            enable=self.setting("watchdog.enable", self.require(m, "watchdog", "enable")),
            timeout_register=self.setting("watchdog.timeout_register",
                                          self.require(m, "watchdog", "timeout_register")),
            actions=tuple(actions),
            feed=self.setting("watchdog.feed", m["feed"]) if m.get("feed") is not None else None,
            timeout=timeout, **strict,
        )

    def setting(self, key: str, value: Any, default_type: str = "uint32") -> Register:
        """A configuration register of the device (holding table): a count, a
        timeout in `scale` s, or a value in volts."""
        m = self.mapping(key, value, ("address", "type", "word_order", "scale"))
        reg_type = self.choice(f"{key}.type", m.get("type", default_type), SETTING_TYPES)
        address = self.integer(f"{key}.address", self.require(m, key, "address"), 0,
                               MAX_ADDRESS - (1 if reg_type in ("float32", "uint32") else 0))
        word_order = self.choice(f"{key}.word_order", m.get("word_order", "big"), WORD_ORDERS)
        scale = self.number(f"{key}.scale", m.get("scale", 1.0), 0.0, lo_open=True)
        return Register("holding", address, reg_type, word_order, scale)  # type: ignore[arg-type]

    def _no_overlap(self, inputs: Mapping[str, Register], outputs: Mapping[str, Output],
                    watchdog: Watchdog | None = None) -> None:
        """Two channels sharing a register is a typo that would read one tank twice
        (or arm the watchdog over a pump's output)."""
        owner: dict[tuple[str, int], str] = {}
        regs = [(f"inputs.{n}", r) for n, r in inputs.items()]
        regs += [(f"outputs.{n}", o.register) for n, o in outputs.items()]
        regs += watchdog.registers() if watchdog is not None else []
        for key, reg in regs:
            for a in reg.span:
                if (reg.table, a) in owner:
                    self.fail(f"{key}.address", f"{reg.table} register {a} is also used by {owner[reg.table, a]}")
                owner[reg.table, a] = key
