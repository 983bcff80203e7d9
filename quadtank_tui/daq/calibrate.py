"""The steady-state calibration procedure (Desautel 2.3; feature B9) on a rig.

For each pump voltage the pumps are held, the four raw sensor voltages are read
until they have settled (every one within `tol` volts over the last `window` reads),
then the operator reads the heights off the tanks' scales.  The pairs (settled volts,
height) give each sensor's gain and offset by least squares; with the plant's pumps
and valves they give its outlet areas too (core.calibration).

The pairs can also come from a file, one settled state a row, with a header naming
the columns (any of u1 u2 volts1..volts4 level1..level4)::

    # pumps (V)   sensors (V)                       scales (cm)
    u1  u2   volts1 volts2 volts3 volts4   level1 level2 level3 level4
    2.0 2.0  2.725  2.841  0.363  0.313    5.45   5.68   0.73   0.63

I/O (the backend, sleeping, asking) is injected, so the procedure runs as well on a
virtual rig in a test as on the lab's.  :func:`with_calibration` puts the fitted
sensors into a DAQ configuration's text, line by line, so its comments survive.
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Protocol, Sequence

from quadtank_tui.core.calibration import (
    CalibrationError,
    OutletFit,
    SensorCalibration,
    fit_quadtank_outlets,
    fit_sensor,
)
from quadtank_tui.core.plant import FULL_SCALE_V, PlantParams

COLUMNS = ("u1", "u2", *(f"volts{i}" for i in range(1, 5)), *(f"level{i}" for i in range(1, 5)))


class RawSensors(Protocol):
    """What the procedure needs of a DAQ backend (ModbusBackend has it)."""

    def read_raw_volts(self) -> tuple[float, ...]: ...
    def write_pumps(self, u: tuple[float, float]) -> None: ...
    def safe_state(self) -> None: ...


@dataclass
class Pairs:
    """Settled states: columns by name (u1, volts3, level2, ...), one value per state."""

    columns: dict[str, list[float]] = field(default_factory=dict)

    def add(self, row: dict[str, float]) -> None:
        for k, v in row.items():
            self.columns.setdefault(k, []).append(float(v))

    def tanks(self) -> list[int]:
        """Tanks with both a sensor and a scale column."""
        return [i for i in range(1, 5) if f"volts{i}" in self.columns and f"level{i}" in self.columns]

    def format(self) -> str:
        """The pairs as a file :func:`parse_pairs` reads back."""
        names = [c for c in COLUMNS if c in self.columns]
        rows = zip(*(self.columns[c] for c in names))
        return "\n".join([" ".join(names), *(" ".join(f"{v:.6g}" for v in r) for r in rows)]) + "\n"


def parse_pairs(text: str, name: str = "<pairs>") -> Pairs:
    """Read a pairs table (see the module docstring); errors name the file and line."""
    pairs = Pairs()
    header: list[str] | None = None
    for no, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        words = line.replace(",", " ").split()
        if header is None:
            bad = [w for w in words if w not in COLUMNS]
            if bad or len(set(words)) != len(words):
                why = f"unknown column {bad[0]!r}" if bad else "a column is repeated"
                raise CalibrationError(f"{name}, line {no}: {why}; columns are {' '.join(COLUMNS)}")
            header = words
            continue
        if len(words) != len(header):
            raise CalibrationError(f"{name}, line {no}: {len(words)} values for {len(header)} columns")
        try:
            values = [float(w) for w in words]
        except ValueError:
            raise CalibrationError(f"{name}, line {no}: not a number in {line!r}") from None
        if not all(math.isfinite(v) for v in values):
            raise CalibrationError(f"{name}, line {no}: every value must be finite")
        pairs.add(dict(zip(header, values)))
    if header is None or not pairs.columns:
        raise CalibrationError(f"{name}: no header and rows (see `quadtank daq calibrate --help`)")
    if not pairs.tanks():
        raise CalibrationError(f"{name}: no tank has both a voltsN and a levelN column")
    return pairs


def read_pairs(path: Path | str) -> Pairs:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise CalibrationError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibrationError(f"{path}: cannot read: {exc}") from None
    return parse_pairs(text, str(path))


@dataclass(frozen=True)
class Settle:
    """When the sensors count as settled: `window` reads `poll` s apart all within
    `tol` V; give up after `timeout` s at one voltage."""

    poll: float = 2.0
    window: int = 30
    tol: float = 0.004
    timeout: float = 3600.0


def settle(sensors: RawSensors, u: tuple[float, float], rule: Settle, *,
           sleep: Callable[[float], None] = time.sleep,
           now: Callable[[], float] = time.monotonic) -> tuple[float, float, float, float]:
    """Hold the pumps at `u` (normalized) until the sensors settle; the mean of the
    last window.  CalibrationError after the timeout (the pumps stay where they are:
    the caller stops them)."""
    start = now()
    recent: list[tuple[float, float, float, float]] = []
    while True:
        sensors.write_pumps(u)  # every read: the rig's watchdog sees the link alive
        recent = (recent + [sensors.read_raw_volts()])[-rule.window:]
        if len(recent) == rule.window and all(
                max(r[i] for r in recent) - min(r[i] for r in recent) <= rule.tol for i in range(4)):
            return tuple(sum(r[i] for r in recent) / rule.window for i in range(4))  # type: ignore[return-value]
        if now() - start > rule.timeout:
            raise CalibrationError(f"the sensors did not settle within {rule.timeout:g} s at "
                                   f"{u[0] * FULL_SCALE_V:g} V / {u[1] * FULL_SCALE_V:g} V")
        sleep(rule.poll)


def run_procedure(sensors: RawSensors, pump_volts: Sequence[tuple[float, float]], rule: Settle,
                  heights: Callable[[tuple[float, float], tuple[float, ...]], Sequence[float]], *,
                  sleep: Callable[[float], None] = time.sleep,
                  now: Callable[[], float] = time.monotonic,
                  report: Callable[[str], None] = lambda text: None) -> Pairs:
    """The whole procedure; the pumps end at 0 whatever happens.

    `heights(volts_pair, settled_sensor_volts)` asks the operator for the four levels
    read on the scales (cm)."""
    pairs = Pairs()
    try:
        for v in pump_volts:
            report(f"pumps at {v[0]:g} V / {v[1]:g} V: waiting for the levels to settle ...")
            settled = settle(sensors, (v[0] / FULL_SCALE_V, v[1] / FULL_SCALE_V), rule, sleep=sleep, now=now)
            report("settled: sensors " + " ".join(f"{x:.4f}" for x in settled) + " V")
            levels = [float(h) for h in heights(v, settled)]
            if len(levels) != 4:
                raise CalibrationError(f"four heights are needed, got {len(levels)}")
            pairs.add({"u1": v[0], "u2": v[1], **{f"volts{i + 1}": settled[i] for i in range(4)},
                       **{f"level{i + 1}": levels[i] for i in range(4)}})
    finally:
        sensors.safe_state()
    return pairs


@dataclass(frozen=True)
class Result:
    """The fits: each tank's sensor calibration, the outlet areas when the plant is given."""

    sensors: dict[int, SensorCalibration]
    outlets: OutletFit | None


def fit_pairs(pairs: Pairs, plant: PlantParams | None = None) -> Result:
    """Gain and offset per tank (2.3.2-2.3.3); outlet areas a1..a4 from the scale
    levels and the pump voltages when `plant` (pumps, valves) is given."""
    c = pairs.columns
    sensors = {i: fit_sensor(c[f"volts{i}"], c[f"level{i}"]) for i in pairs.tanks()}
    outlets = None
    needed = ("u1", "u2", "level1", "level2", "level3", "level4")
    if plant is not None and all(k in c for k in needed):
        outlets = fit_quadtank_outlets(
            list(zip(c["u1"], c["u2"])), list(zip(*(c[f"level{i}"] for i in range(1, 5)))),
            (plant.k1, plant.k2), (plant.gamma1, plant.gamma2), g=plant.g)
    return Result(sensors, outlets)


def format_result(r: Result, plant: PlantParams | None = None) -> str:
    lines = []
    for i, cal in r.sensors.items():
        lines.append(f"tank {i}  gain {cal.gain:.4f} cm/V  offset {cal.offset:+.4f} cm  "
                     f"rms residual {cal.rms:.3f} cm")
    lines.append("for the DAQ configuration's calibration section:")
    lines += [f"  tank{i}: {{gain: {cal.gain:.4f}, offset: {cal.offset:.4f}}}" for i, cal in r.sensors.items()]
    if r.outlets is not None:
        lines.append(f"outlet areas from the scale levels (flow rms {r.outlets.rms:.3g} cm^3/s):")
        for i, a in enumerate(r.outlets.coefficients, start=1):
            known = f"   (.par: {plant.outlet(i - 1):.4f})" if plant is not None else ""
            lines.append(f"  a{i} {a:.4f} cm^2{known}")
    return "\n".join(lines)


_TANK_LINE = r"^([ \t]*)tank{i}:[ \t]*\{{[^}}\n]*\}}[ \t]*(#[^\n]*)?$"


def with_calibration(text: str, sensors: dict[int, SensorCalibration]) -> str:
    """The DAQ configuration `text` with each fitted tank's `tankN: {gain, offset}`
    line replaced (comments kept), or added under `calibration:` (the section added
    at the end when there is none)."""
    for i, cal in sorted(sensors.items(), reverse=True):  # each added line goes first
        value = f"{{gain: {cal.gain:.6g}, offset: {cal.offset:.6g}}}"
        pattern = re.compile(_TANK_LINE.format(i=i), re.MULTILINE)
        if pattern.search(text):
            text = pattern.sub(lambda m: f"{m.group(1)}tank{i}: {value}" + (f"  {m.group(2)}" if m.group(2) else ""),
                               text, count=1)
            continue
        if re.search(rf"^[ \t]*tank{i}:", text, re.MULTILINE):
            raise CalibrationError(f"tank{i} is not written on one line as {{gain: ..., offset: ...}}: "
                                   "paste the printed lines yourself")
        section = re.search(r"^calibration:[ \t]*(#[^\n]*)?$", text, re.MULTILINE)
        if section is None:
            text = text.rstrip("\n") + "\n\ncalibration:\n"
            section = re.search(r"^calibration:[ \t]*$", text, re.MULTILINE)
        assert section is not None
        text = text[: section.end()] + f"\n  tank{i}: {value}" + text[section.end():]
    return text
