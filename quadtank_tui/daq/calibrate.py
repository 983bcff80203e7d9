"""The steady-state calibration procedure (Desautel 2.3; feature B9) on a rig.

For each pump voltage the pumps are held, the four raw sensor voltages are read
until they have settled (every one within `tol` volts over the last `window` reads),
then the operator reads the heights off the tanks' scales: the one procedure of
core.calibration.procedure, which the engine runs sample by sample in the TUI's
Calibration window, here in a loop paced by sleeps.  The pairs (settled volts,
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
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Protocol, Sequence, TypeVar

from quadtank_tui.core.calibration.fits import (
    CalibrationError,
    OutletFit,
    SensorCalibration,
    fit_cascade_outlets,
    fit_quadtank_outlets,
    fit_sensor,
)
from quadtank_tui.core.calibration.procedure import FAILED, SETTLING, CalibrationRun, SettleRule
from quadtank_tui.core.parameters import Parameters
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.plants.johansson import PlantParams, area_from_diameter, time_constant
from quadtank_tui.core.plants import CoupledCascade, Plant, QuadTank

COLUMNS = ("u1", "u2", *(f"volts{i}" for i in range(1, 5)), *(f"level{i}" for i in range(1, 5)))


class RawSensors(Protocol):
    """What the procedure needs of a DAQ backend (ModbusBackend has it)."""

    def read_raw_volts(self) -> tuple[float, ...]: ...
    def write_pumps(self, u: tuple[float, float]) -> None: ...
    def safe_state(self) -> None: ...
    def arm(self, tsamp: float) -> None: ...


T = TypeVar("T")


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


#: The largest pairs file read, bytes: a calibration has a few dozen settled states
#: (a line each); `--pairs /dev/zero` grew to 11.9 GB before a MemoryError.
MAX_PAIRS_BYTES = 1_000_000


def read_pairs(path: Path | str) -> Pairs:
    """The pairs of a regular file of at most MAX_PAIRS_BYTES (a device, a FIFO or a
    directory is refused, never read)."""
    from quadtank_tui.files.regular import read_regular

    try:
        data = read_regular(path, MAX_PAIRS_BYTES)
    except FileNotFoundError:
        raise CalibrationError(f"{path}: no such file") from None
    except OSError as exc:
        raise CalibrationError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if len(data) > MAX_PAIRS_BYTES:
        raise CalibrationError(f"{path}: larger than {MAX_PAIRS_BYTES:,} bytes: not a file of settled pairs")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CalibrationError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    return parse_pairs(text, str(path))


def run_procedure(sensors: RawSensors, pump_volts: Sequence[float], rule: SettleRule,
                  heights: Callable[[tuple[float, float], tuple[float, ...]], Sequence[float]], *,
                  poll: float = 2.0, sleep: Callable[[float], None] = time.sleep,
                  now: Callable[[], float] = time.monotonic,
                  report: Callable[[str], None] = lambda text: None) -> Pairs:
    """The procedure (core.calibration.procedure.CalibrationRun) on a rig, a read every
    `poll` s, each voltage of `pump_volts` on both pumps; the pumps end at 0 whatever
    happens.  CalibrationError when the sensors do not settle within the rule's
    timeout at a voltage, or the heights given are not four numbers >= 0.

    `heights(volts_pair, settled_sensor_volts)` asks the operator for the four levels
    read on the scales (cm)."""
    run = CalibrationRun(pump_volts, rule, h=poll)
    try:
        # Armed as a run is (the device's watchdog and the guard process, for one
        # exchange every `poll` s): killed mid-procedure, the pumps stop.
        sensors.arm(poll)
        while run.active:
            v = run.pumps()
            report(f"pumps at {v[0]:g} V / {v[1]:g} V: waiting for the levels to settle ...")
            u = (v[0] / FULL_SCALE_V, v[1] / FULL_SCALE_V)
            last = now()
            while True:
                sensors.write_pumps(u)  # every read: the rig's watchdog sees the link alive
                read = sensors.read_raw_volts()
                t = now()
                if run.feed(read, t - last) != SETTLING:
                    break
                last = t
                sleep(poll)
            if run.phase == FAILED:
                raise CalibrationError(run.message)
            settled = run.settled
            report("settled: sensors " + " ".join(f"{x:.4f}" for x in settled) + " V")
            run.heights(hold_while(sensors, u, poll, lambda: heights(v, settled)))
    finally:
        sensors.safe_state()
    pairs = Pairs()
    pairs.columns = {k: list(col) for k, col in run.columns.items()}
    return pairs


def hold_while(sensors: RawSensors, u: tuple[float, float], poll: float, ask: Callable[[], T]) -> T:
    """`ask()` (the operator reading the scales: minutes, perhaps) on a thread of
    its own while this one keeps the pumps at `u` and the link alive every `poll`
    s: the levels must stay where they settled while they are read, and the rig's
    watchdog, armed for `poll`, must keep hearing from us.  The question's thread
    is a daemon: Ctrl-C here ends the procedure (pumps to 0) without waiting for
    an answer."""
    answer: list[T] = []
    failed: list[BaseException] = []
    done = threading.Event()

    def question() -> None:
        try:
            answer.append(ask())
        except BaseException as exc:  # handed to the procedure's thread, raised there
            failed.append(exc)
        finally:
            done.set()

    threading.Thread(target=question, name="calibration-question", daemon=True).start()
    while not done.wait(poll):
        sensors.write_pumps(u)
        sensors.read_raw_volts()
    if failed:
        raise failed[0]
    return answer[0]


@dataclass(frozen=True)
class Result:
    """The fits: each tank's sensor calibration, and the plant's outlet coefficients
    (named `outlet_names`, in `outlet_unit`) when the plant is given."""

    sensors: dict[int, SensorCalibration]
    outlets: OutletFit | None
    outlet_names: tuple[str, ...] = ()
    outlet_unit: str = ""


def fit_pairs(pairs: Pairs, plant: PlantParams | Plant | None = None) -> Result:
    """Gain and offset per tank (2.3.2-2.3.3); with the plant, its outlets from the
    scale levels and the pump voltages: the quadruple tank's areas a1..a4 (its pumps
    and valves known), the cascade's alpha1, alpha2 (Desautel 2.3.1, beta1 known)."""
    c = pairs.columns
    sensors = {i: fit_sensor(c[f"volts{i}"], c[f"level{i}"]) for i in pairs.tanks()}
    if isinstance(plant, QuadTank):
        plant = plant.params
    if isinstance(plant, PlantParams) and all(k in c for k in ("u1", "u2", *(f"level{i}" for i in range(1, 5)))):
        fit = fit_quadtank_outlets(
            list(zip(c["u1"], c["u2"])), list(zip(*(c[f"level{i}"] for i in range(1, 5)))),
            (plant.k1, plant.k2), (plant.gamma1, plant.gamma2), g=plant.g)
        return Result(sensors, fit, ("a1", "a2", "a3", "a4"), "cm^2")
    if isinstance(plant, CoupledCascade) and all(k in c for k in ("u1", "level1", "level2")):
        fit = fit_cascade_outlets(c["u1"], c["level1"], c["level2"], plant.beta1, plant.g)
        return Result(sensors, fit, ("alpha1", "alpha2"), "")
    return Result(sensors, None)


def par_values(params: Parameters, r: Result) -> dict[str, str]:
    """The `.par` entries the outlet fit sets, as the file writes them: the quadruple
    tank's TimeConst1..4 (its outlets at the file's diameters and operating levels,
    a = A sqrt(2 h0 / g) / T), the cascade's PLANT alpha1, alpha2 (five digits, as
    Desautel gives them)."""
    if r.outlets is None:
        return {}
    if r.outlet_names[0] == "a1":
        if params.process is not None:
            raise CalibrationError(f"the outlet areas are the quadruple tank's, the file's plant is "
                                   f"{params.process.kind}")
        sim = params.simulation
        h0 = sim.operating_levels()
        return {f"SIMULATION.TimeConst{i + 1}": "%f" % time_constant(
                    area_from_diameter(sim.diameters[i]), a, h0[i], PlantParams.g)
                for i, a in enumerate(r.outlets.coefficients)}
    return {f"PLANT.{name}": f"{a:.5g}" for name, a in zip(r.outlet_names, r.outlets.coefficients)}


def format_result(r: Result, plant: PlantParams | Plant | None = None, *, config_lines: bool = True) -> str:
    """The fits as text: per sensor, the lines for the DAQ configuration (unless not
    `config_lines`), the outlets next to the plant's."""
    lines = []
    for i, cal in r.sensors.items():
        lines.append(f"tank {i}  gain {cal.gain:.4f} cm/V  offset {cal.offset:+.4f} cm  "
                     f"rms residual {cal.rms:.3f} cm")
    if config_lines:
        lines.append("for the DAQ configuration's calibration section:")
        lines += [f"  tank{i}: {{gain: {cal.gain:.4f}, offset: {cal.offset:.4f}}}" for i, cal in r.sensors.items()]
    if r.outlets is not None:
        known = _known_outlets(plant)
        flow = "cm^3/s" if r.outlet_unit else "cm/s"
        lines.append(f"outlets from the scale levels (flow rms {r.outlets.rms:.3g} {flow}):")
        for i, (name, a) in enumerate(zip(r.outlet_names, r.outlets.coefficients)):
            was = f"   (.par: {known[i]:.{4 if r.outlet_unit else 7}f})" if known else ""
            value = f"{a:.4f} {r.outlet_unit}" if r.outlet_unit else f"{a:.7f}"
            lines.append(f"  {name} {value}{was}")
    return "\n".join(lines)


def _known_outlets(plant: PlantParams | Plant | None) -> tuple[float, ...]:
    if isinstance(plant, QuadTank):
        plant = plant.params
    if isinstance(plant, PlantParams):
        return tuple(plant.outlet(i) for i in range(4))
    if isinstance(plant, CoupledCascade):
        return (plant.alpha1, plant.alpha2)
    return ()


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


@dataclass(frozen=True)
class Planned:
    """One file a calibration changes: its text before and after."""

    path: Path
    old: str
    new: str

    def diff(self) -> str:
        from quadtank_tui.files.par_edit import text_diff

        return text_diff(self.old, self.new, str(self.path))


def plan_writes(r: Result, daq_file: Path | str | None, par_file: Path | str | None) -> list[Planned]:
    """What writing `r` changes: the sensors into the DAQ configuration file, the
    outlets into the `.par` (when fitted).  Each new text is checked by its reader
    first, so a file it would refuse is never planned; files that would not change
    are left out.  CalibrationError (or the reader's error) says why not."""
    from quadtank_tui.daq.config import parse_daq_config
    from quadtank_tui.files.par import parse_par
    from quadtank_tui.files.par_edit import with_par_values

    out = []
    if daq_file is not None and r.sensors:
        old = _read(daq_file)
        new = with_calibration(old, r.sensors)
        parse_daq_config(new, name=str(daq_file))
        out.append(Planned(Path(daq_file), old, new))
    if par_file is not None and r.outlets is not None:
        old = _read(par_file)
        values = par_values(parse_par(old, name=str(par_file)).params, r)
        new = with_par_values(old, values, str(par_file))
        parse_par(new, name=str(par_file))
        out.append(Planned(Path(par_file), old, new))
    return [p for p in out if p.new != p.old]


def commit(planned: Sequence[Planned]) -> None:
    """Write each planned file atomically (an interrupted write leaves it as it was)."""
    from quadtank_tui.files.atomic import atomic_write_text

    for p in planned:
        atomic_write_text(p.path, p.new, encoding="utf-8")


def _read(path: Path | str) -> str:
    try:
        return Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise CalibrationError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise CalibrationError(f"{path}: not a text file") from None
