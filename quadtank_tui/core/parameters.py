"""All of the interface's parameters in one typed, frozen, validated model.

The engine and the UI read their settings from :class:`Parameters`; a `.par` file
is its serialization (``quadtank_tui.files.par``).  Every parameter has a name
``"SECTION.Key"`` exactly as in the `.par` file ("SAMPLING TIME.TSamp",
"REFERENCE ONE.Mean", "CONTROLLER ONE.K", "SIMULATION.Valve1", ...).  Those names
are the public handle: :meth:`Parameters.get`, :meth:`Parameters.with_value`,
:meth:`Parameters.modified_keys`, the scripted experiments and the file reader all
use them, so a parameter cannot be known to one and missing from another.

Ranges live here and only here (the reference and controller ranges in
``WaveParams``/``PIDParams``/``GeneralParams``, which this model composes); a
refused value raises :class:`ParameterError` whose ``field`` is the full key.

The built-in values, :data:`PRESET`, are the paper's minimum-phase setting P- with
the thesis's decentralized PI controllers (3.0, 30) and (2.7, 40) and a sampling
time of 100 ms.  Derived values (diameters from the areas, normalized operating
points, time constants) are rounded to the six decimals of the file format, so the
shipped `.par` files look like the original's and hold the values exactly.

Example
-------
>>> p = PRESET.with_value("CONTROLLER ONE.K", 2.5)
>>> p.get("CONTROLLER ONE.K"), sorted(p.modified_keys())
(2.5, ['CONTROLLER ONE.K'])
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from enum import Enum
from typing import Any, Iterable, Iterator, Mapping, Sequence

from quadtank_tui.core.general import GeneralParams
from quadtank_tui.core.matrix import Family, Structure
from quadtank_tui.core.pid import PIDParams
from quadtank_tui.core.plant import (
    FULL_SCALE_V,
    P_MINUS,
    P_PLUS,
    Levels,
    PlantParams,
    Setting,
    area_from_diameter,
    diameter_from_area,
    levels_to_normalized,
    outlet_from_time_constant,
    time_constant,
)
from quadtank_tui.core.plants import Plant, QuadTank
from quadtank_tui.core.plants.spec import PlantSpec
from quadtank_tui.core.signals import Wave, WaveParams
from quadtank_tui.core.statefb.settings import StateFeedbackParams
from quadtank_tui.core.validation import ParameterError, check_number, check_range


class ControlMode(str, Enum):
    """Manual: the generators drive u1, u2; Automatic: they drive the references."""

    MANUAL = "Manual"
    AUTOMATIC = "Automatic"


#: Sampling time range, ms (thesis 5.4: "50 ms ... a few seconds").
TSAMP_MIN_MS = 50.0
TSAMP_MAX_MS = 10_000.0
#: The original's LogOn collected at most 5000 points.  We allow more because a P+
#: step settles in ~800 s, longer than 5000 samples at 100 ms; files of the
#: original never exceed 5000, so reading them is unaffected.
POINTS_MAX_ORIGINAL = 5000
POINTS_MAX = 100_000
#: Smallest operating point (normalized level): 0.2 mm at kc = 0.5 V/cm.  Any
#: positive number used to pass, and 4.9e-324 then failed in plant() with no file,
#: line or key (its outlet area underflowed to 0).
OP_POINT_MIN = 0.001
#: Columns a `.log` may hold, in the order the Logging window lists them.
LOG_VARIABLES = ("t", "y1", "y2", "y3", "y4", "u1", "u2", "r1", "r2")
#: Plot types of the two trends (thesis Figure 35).
PLOT_TYPES = ("u1", "u2", "u1 u2", "y1 ref1", "y2 ref2", "y1 y2 ref1 ref2", "y1 y2 y3 y4")
#: Largest magnitude accepted for a number without a narrower range (General
#: coefficients): beyond it a value is a typo or junk, not a controller.
MAX_ABS = 1e9

_FILE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]{0,99}")


# --- validation helpers ----------------------------------------------------------------

def _enum(key: str, enum: type[Enum], value: Any) -> Any:
    if isinstance(value, enum):
        return value
    try:
        return enum(value)
    except ValueError:
        allowed = ", ".join(str(m.value) for m in enum)
        raise ParameterError(key, f"must be one of {allowed}; got {value!r}") from None


def _whole(key: str, value: Any) -> int:
    x = check_number(key, value)
    if x != int(x):
        raise ParameterError(key, f"must be a whole number, got {x:g}")
    return int(x)


def _integer(key: str, value: Any, lo: int, hi: int) -> int:
    return int(check_range(key, _whole(key, value), lo, hi))


def check_file_name(name: Any, key: str = "LogFile") -> str:
    """A file name (log or parameter file) is a name, not a path: letters, digits,
    `_`, `-`, `.`; it may not start with a dot or contain `..`, so it cannot leave
    its folder (`logs/`, `params/`) whatever the user types."""
    if not isinstance(name, str) or not _FILE_NAME.fullmatch(name) or ".." in name:
        raise ParameterError(
            key, f"must be a plain file name (letters, digits, _ - .; no folders), got {name!r}"
        )
    return name


def check_variables(key: str, names: Sequence[str]) -> tuple[str, ...]:
    """Log columns: a non-empty, repeat-free choice from :data:`LOG_VARIABLES`."""
    names = tuple(names)
    bad = [n for n in names if n not in LOG_VARIABLES]
    if not names or bad or len(set(names)) != len(names):
        why = f"unknown {' '.join(bad)}" if bad else ("none given" if not names else "a name is repeated")
        raise ParameterError(key, f"must be distinct names from {' '.join(LOG_VARIABLES)} ({why})")
    return names


def _check_period(section: str, ref: WaveParams, tsamp_ms: float) -> None:
    """Refuse a period the sampling time cannot render (thesis 5.4: below twice the
    sampling time the original silently produced a constant)."""
    key = f"{section}.Period"
    if ref.wave is Wave.PRBS:
        if ref.period < 1 or ref.period != int(ref.period):
            raise ParameterError(key, f"a PRBS period is a whole number of samples >= 1, got {ref.period:g}")
    elif ref.period < 2 * tsamp_ms / 1000.0:
        raise ParameterError(
            key, f"{ref.period:g} s is shorter than twice the sampling time ({tsamp_ms / 1000.0:g} s): "
            f"the shortest allowed is {2 * tsamp_ms / 1000.0:g} s"
        )



@dataclass(frozen=True)
class ControlSettings:
    """CONTROL section: mode and the controller matrix's type."""

    mode: ControlMode = ControlMode.MANUAL
    family: Family = Family.PID
    structure: Structure = Structure.DECENTRALIZED

    def __post_init__(self) -> None:
        for attr, key, enum in (("mode", "Mode", ControlMode), ("family", "Type", Family),
                                ("structure", "Structure", Structure)):
            object.__setattr__(self, attr, _enum(key, enum, getattr(self, attr)))


@dataclass(frozen=True)
class ControllerElement:
    """One element of the 2x2 matrix: it keeps both families' parameters, so
    switching the type and back restores what was set (as the original did)."""

    pid: PIDParams = PIDParams()
    general: GeneralParams = GeneralParams()


@dataclass(frozen=True)
class SimulationSettings:
    """SIMULATION section, as the Setup screen shows it.

    diameters : tank inner diameters, cm
    op_points : operating levels, normalized (fraction of the 10 V sensor range)
    time_constants : linearized time constants at the operating levels, s
    valves : gamma1, gamma2, fraction of each pump's flow to its lower tank
    pumps : k1, k2, cm^3/(V s)
    sensor : kc, V/cm; the sensor range 10 V / kc is the tank height

    The outlet areas are not stored: they follow from the other three values of a
    tank (control.md), which keeps them consistent however they were edited.
    """

    diameters: tuple[float, float, float, float]
    op_points: tuple[float, float, float, float]
    time_constants: tuple[float, float, float, float]
    valves: tuple[float, float]
    pumps: tuple[float, float]
    sensor: float

    def __post_init__(self) -> None:
        if not (len(self.diameters) == len(self.op_points) == len(self.time_constants) == 4):
            raise ParameterError("Diameter1", "four tanks are needed")
        for i in range(4):
            check_range(f"Diameter{i + 1}", self.diameters[i], 0.5, 100.0)
            check_range(f"OpPoint{i + 1}", self.op_points[i], OP_POINT_MIN, 1.0)
            check_range(f"TimeConst{i + 1}", self.time_constants[i], 1.0, 1e5)
        for i in range(2):
            check_range(f"Valve{i + 1}", self.valves[i], 0.0, 1.0)
            check_range(f"Pump{i + 1}", self.pumps[i], 0.0, 100.0, lo_open=True)
        check_range("Sensor", self.sensor, 0.05, 10.0)

    def operating_levels(self) -> Levels:
        """Operating levels in cm: h0 = OpPoint * 10 V / kc."""
        h = [op * FULL_SCALE_V / self.sensor for op in self.op_points]
        return (h[0], h[1], h[2], h[3])

    def plant(self) -> PlantParams:
        """The physical constants these settings describe.

        A_i = pi d_i^2 / 4 and a_i = A_i sqrt(2 h0_i / g) / T_i; the tank height is
        the sensor range.  The ranges above guarantee a_i < A_i (T >= 1 s,
        h0 <= 200 cm), so this never fails for a validated model.
        """
        g = PlantParams.g
        h0 = self.operating_levels()
        areas = [area_from_diameter(d) for d in self.diameters]
        outlets = [outlet_from_time_constant(areas[i], self.time_constants[i], h0[i], g) for i in range(4)]
        return PlantParams(
            A1=areas[0], A2=areas[1], A3=areas[2], A4=areas[3],
            a1=outlets[0], a2=outlets[1], a3=outlets[2], a4=outlets[3],
            k1=self.pumps[0], k2=self.pumps[1],
            gamma1=self.valves[0], gamma2=self.valves[1],
            kc=self.sensor, g=g, hmax=FULL_SCALE_V / self.sensor,
        )

    @classmethod
    def from_setting(cls, setting: Setting) -> SimulationSettings:
        """The Setup-screen view of a physical setting, rounded to six decimals."""
        p = setting.params
        h = setting.op.h
        return cls(
            # Each a tuple of exactly four (one per tank), which tuple() cannot tell mypy.
            diameters=tuple(round(diameter_from_area(p.area(i)), 6) for i in range(4)),  # type: ignore[arg-type]
            op_points=tuple(round(y, 6) for y in levels_to_normalized(h, p)),  # type: ignore[arg-type]
            time_constants=tuple(  # type: ignore[arg-type]
                round(time_constant(p.area(i), p.outlet(i), h[i], p.g), 6) for i in range(4)
            ),
            valves=(p.gamma1, p.gamma2),
            pumps=(p.k1, p.k2),
            sensor=p.kc,
        )


@dataclass(frozen=True)
class LoggingSettings:
    """LOGGING section: how many points LogOn collects, the file name (without
    `.log`), and the logged columns in order."""

    points: int = POINTS_MAX_ORIGINAL
    log_file: str = "data"
    variables: tuple[str, ...] = ("y1", "y2", "u1", "u2")

    def __post_init__(self) -> None:
        _integer("Points", self.points, 1, POINTS_MAX)
        check_file_name(self.log_file)
        check_variables("Variables", self.variables)


@dataclass(frozen=True)
class PlotSettings:
    """PLOTS section: the plot type of the upper and lower trend (thesis Fig. 35)."""

    upper: str = "u1 u2"
    lower: str = "y1 y2 ref1 ref2"

    def __post_init__(self) -> None:
        for attr, key in (("upper", "Upper"), ("lower", "Lower")):
            value = getattr(self, attr)
            text = " ".join(value.split()) if isinstance(value, str) else value
            if text not in PLOT_TYPES:
                raise ParameterError(key, f"must be one of {', '.join(PLOT_TYPES)}; got {value!r}")
            object.__setattr__(self, attr, text)


@dataclass(frozen=True)
class Parameters:
    """Every parameter of the interface (one `.par` file's worth).

    tsamp_ms : sampling time of controllers and simulation, ms (kept in the file's
        unit so a saved value reloads exactly; :attr:`tsamp` gives seconds)
    references : generators 1 and 2 (u1/u2 in Manual, ref1/ref2 in Automatic)
    controllers : elements 11, 12, 21, 22 (CONTROLLER ONE..FOUR)
    statefb : the state-feedback controller's settings (STATE FEEDBACK; files
        without the section get the defaults)
    extra : unknown `(section, key, value)` entries read from a file, kept so that
        saving writes them back; they have no effect
    process : the plant when it is not the quadruple tank of the SIMULATION section
        (a `.par` file's PLANT section; None for every file written before it)
    """

    tsamp_ms: float
    references: tuple[WaveParams, WaveParams]
    control: ControlSettings
    controllers: tuple[ControllerElement, ControllerElement, ControllerElement, ControllerElement]
    simulation: SimulationSettings
    logging: LoggingSettings = LoggingSettings()
    plots: PlotSettings = PlotSettings()
    statefb: StateFeedbackParams = StateFeedbackParams()
    extra: tuple[tuple[str, str, str], ...] = ()
    process: PlantSpec | None = None

    def __post_init__(self) -> None:
        check_range(TSAMP, self.tsamp_ms, TSAMP_MIN_MS, TSAMP_MAX_MS)
        if len(self.references) != 2:
            raise ParameterError("REFERENCE ONE", f"two references are needed, got {len(self.references)}")
        if len(self.controllers) != 4:
            raise ParameterError("CONTROLLER ONE", f"four controller elements are needed, got {len(self.controllers)}")
        for section, ref in zip(REFERENCE_SECTIONS, self.references):
            _check_period(section, ref, self.tsamp_ms)

    @property
    def tsamp(self) -> float:
        """Sampling time, s."""
        return self.tsamp_ms / 1000.0

    # --- generic access by "SECTION.Key" ----------------------------------------

    def get(self, key: str) -> Any:
        """The value of parameter `key` ("SECTION.Key"); KeyError if unknown."""
        return _walk(self, spec(key).path)

    def values(self) -> dict[str, Any]:
        """Every parameter by key, in file order."""
        return {k.name: _walk(self, k.path) for k in KEYS}

    def with_value(self, key: str, value: Any) -> Parameters:
        """A copy with one parameter changed (validated; ParameterError names `key`)."""
        return self.with_values({key: value})

    def with_values(self, changes: Mapping[str, Any]) -> Parameters:
        """A copy with several parameters changed at once.

        Applied together, then validated together: a pair of values that is only
        valid jointly (a sampling time and a period) can be set in one call.
        """
        tree = _to_tree(self)
        for key, value in changes.items():
            k = spec(key)
            _set_leaf(tree, k.path, k.coerce(value))
        return _from_tree(self, tree, ())

    def with_defaults(self, keys: Iterable[str], default: Parameters | None = None) -> Parameters:
        """A copy with `keys` back at their default values (a window's Default
        button: e.g. ``p.with_defaults(k.name for k in keys_of("CONTROLLER ONE"))``)."""
        base = PRESET if default is None else default
        return self.with_values({key: base.get(key) for key in keys})

    def modified_keys(self, default: Parameters | None = None) -> frozenset[str]:
        """Keys whose value differs from `default` (the built-in preset if None)."""
        base = (PRESET if default is None else default).values()
        return frozenset(k for k, v in self.values().items() if v != base[k])

    def is_modified(self, key: str, default: Parameters | None = None) -> bool:
        """Whether `key` differs from its default (the UI greys modified values)."""
        return self.get(key) != (PRESET if default is None else default).get(key)

    def plant(self) -> PlantParams:
        """Physical constants of the simulated process (see SimulationSettings.plant)."""
        return self.simulation.plant()

    def operating_levels(self) -> Levels:
        """Operating levels, cm."""
        return self.simulation.operating_levels()

    def process_plant(self) -> Plant:
        """The plant in use, through the plant interface (core.plants)."""
        return QuadTank(self.plant()) if self.process is None else self.process.plant()

    def process_levels(self) -> tuple[float, ...]:
        """Operating levels of the plant in use, in its own length unit."""
        return tuple(self.operating_levels()) if self.process is None else self.process.levels


# --- the key registry ----------------------------------------------------------------

TSAMP = "SAMPLING TIME.TSamp"
REFERENCE_SECTIONS = ("REFERENCE ONE", "REFERENCE TWO")
CONTROLLER_SECTIONS = ("CONTROLLER ONE", "CONTROLLER TWO", "CONTROLLER THREE", "CONTROLLER FOUR")
STATEFB_SECTION = "STATE FEEDBACK"


class Kind(str, Enum):
    """How a value is represented (and so how the file writes it)."""

    NUMBER = "number"
    INTEGER = "integer"
    FLAG = "flag"
    CHOICE = "choice"
    NAME = "name"
    NAMES = "names"


@dataclass(frozen=True)
class KeySpec:
    """One parameter: its `.par` section and key, kind and place in the model."""

    section: str
    key: str
    kind: Kind
    path: tuple[str | int, ...]
    choices: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        return f"{self.section}.{self.key}"

    def coerce(self, value: Any) -> Any:
        """`value` in this key's Python type; ParameterError (naming the key) if it
        cannot be one.  Ranges are checked when the model is rebuilt."""
        try:
            return _COERCE[self.kind](self, value)
        except ParameterError as exc:
            raise ParameterError(self.name, exc.reason) from None


def _coerce_number(k: KeySpec, value: Any) -> float:
    x = check_number(k.key, value)
    if abs(x) > MAX_ABS:
        raise ParameterError(k.key, f"must be within +-{MAX_ABS:g}, got {x:g}")
    return x


def _coerce_integer(k: KeySpec, value: Any) -> int:
    return _whole(k.key, value)


def _coerce_flag(k: KeySpec, value: Any) -> bool:
    if isinstance(value, bool):
        return value
    if isinstance(value, (int, float)) and value in (0, 1):
        return bool(value)
    raise ParameterError(k.key, f"must be 0 or 1, got {value!r}")


def _coerce_choice(k: KeySpec, value: Any) -> str:
    text = " ".join(value.split()) if isinstance(value, str) else None
    for c in k.choices:
        if text is not None and c.lower() == text.lower():
            return c
    raise ParameterError(k.key, f"must be one of {', '.join(k.choices)}; got {value!r}")


def _coerce_name(k: KeySpec, value: Any) -> str:
    if not isinstance(value, str):
        raise ParameterError(k.key, f"must be a name, got {value!r}")
    return value


def _coerce_names(k: KeySpec, value: Any) -> tuple[str, ...]:
    names = value.split() if isinstance(value, str) else value
    if not isinstance(names, (list, tuple)) or not all(isinstance(n, str) for n in names):
        raise ParameterError(k.key, f"must be a list of names, got {value!r}")
    return tuple(names)


_COERCE = {
    Kind.NUMBER: _coerce_number, Kind.INTEGER: _coerce_integer, Kind.FLAG: _coerce_flag,
    Kind.CHOICE: _coerce_choice, Kind.NAME: _coerce_name, Kind.NAMES: _coerce_names,
}


def _build_keys() -> tuple[KeySpec, ...]:
    keys = [KeySpec("SAMPLING TIME", "TSamp", Kind.NUMBER, ("tsamp_ms",))]
    for i, sec in enumerate(REFERENCE_SECTIONS):
        p: tuple[str | int, ...] = ("references", i)
        keys += [
            KeySpec(sec, "Wave", Kind.CHOICE, (*p, "wave"), tuple(w.value for w in Wave)),
            KeySpec(sec, "Mean", Kind.NUMBER, (*p, "mean")),
            KeySpec(sec, "Period", Kind.NUMBER, (*p, "period")),
            KeySpec(sec, "Amplitude", Kind.NUMBER, (*p, "amplitude")),
            KeySpec(sec, "On", Kind.FLAG, (*p, "on")),
            KeySpec(sec, "Seed", Kind.INTEGER, (*p, "seed")),
        ]
    keys += [
        KeySpec("CONTROL", "Mode", Kind.CHOICE, ("control", "mode"), tuple(m.value for m in ControlMode)),
        KeySpec("CONTROL", "Type", Kind.CHOICE, ("control", "family"), tuple(f.value for f in Family)),
        KeySpec("CONTROL", "Structure", Kind.CHOICE, ("control", "structure"), tuple(s.value for s in Structure)),
    ]
    for i, sec in enumerate(CONTROLLER_SECTIONS):
        pid: tuple[str | int, ...] = ("controllers", i, "pid")
        gen: tuple[str | int, ...] = ("controllers", i, "general")
        keys += [KeySpec(sec, k, Kind.NUMBER, (*pid, k)) for k in ("K", "Ti", "Td", "Tr", "N", "a", "b")]
        keys += [KeySpec(sec, "I", Kind.FLAG, (*pid, "integral")), KeySpec(sec, "D", Kind.FLAG, (*pid, "derivative"))]
        keys.append(KeySpec(sec, "Degree", Kind.INTEGER, (*gen, "degree")))
        keys += [KeySpec(sec, f"s{j}", Kind.NUMBER, (*gen, "s", j)) for j in range(5)]
        keys += [KeySpec(sec, f"r{j + 1}", Kind.NUMBER, (*gen, "r", j)) for j in range(4)]
    sim: tuple[str | int, ...] = ("simulation",)
    for i in range(4):
        keys += [
            KeySpec("SIMULATION", f"Diameter{i + 1}", Kind.NUMBER, (*sim, "diameters", i)),
            KeySpec("SIMULATION", f"OpPoint{i + 1}", Kind.NUMBER, (*sim, "op_points", i)),
            KeySpec("SIMULATION", f"TimeConst{i + 1}", Kind.NUMBER, (*sim, "time_constants", i)),
        ]
    keys += [KeySpec("SIMULATION", f"Valve{i + 1}", Kind.NUMBER, (*sim, "valves", i)) for i in range(2)]
    keys += [KeySpec("SIMULATION", f"Pump{i + 1}", Kind.NUMBER, (*sim, "pumps", i)) for i in range(2)]
    keys.append(KeySpec("SIMULATION", "Sensor", Kind.NUMBER, (*sim, "sensor")))
    keys += [
        KeySpec("LOGGING", "Points", Kind.INTEGER, ("logging", "points")),
        KeySpec("LOGGING", "LogFile", Kind.NAME, ("logging", "log_file")),
        KeySpec("LOGGING", "Variables", Kind.NAMES, ("logging", "variables")),
        KeySpec("PLOTS", "Upper", Kind.CHOICE, ("plots", "upper"), PLOT_TYPES),
        KeySpec("PLOTS", "Lower", Kind.CHOICE, ("plots", "lower"), PLOT_TYPES),
    ]
    sf: tuple[str | int, ...] = ("statefb",)
    keys += [
        KeySpec(STATEFB_SECTION, "Ts", Kind.NUMBER, (*sf, "settling_time")),
        KeySpec(STATEFB_SECTION, "Poles", Kind.NAME, (*sf, "poles")),
        KeySpec(STATEFB_SECTION, "L3", Kind.NUMBER, (*sf, "l3")),
        KeySpec(STATEFB_SECTION, "Smart", Kind.FLAG, (*sf, "smart")),
        KeySpec(STATEFB_SECTION, "LevelMargin", Kind.NUMBER, (*sf, "level_margin")),
        KeySpec(STATEFB_SECTION, "Level1", Kind.NUMBER, (*sf, "level1")),
        KeySpec(STATEFB_SECTION, "Level2", Kind.NUMBER, (*sf, "level2")),
    ]
    return tuple(keys)


#: Every parameter, in the order a `.par` file lists them.
KEYS: tuple[KeySpec, ...] = _build_keys()
_BY_NAME = {k.name: k for k in KEYS}
#: Section names in file order.
SECTIONS: tuple[str, ...] = tuple(dict.fromkeys(k.section for k in KEYS))
#: Which section owns each object of the model (for naming errors of nested types).
_SECTION_OF_PATH = {
    k.path[: len(k.path) - (2 if isinstance(k.path[-1], int) else 1)]: k.section for k in KEYS if len(k.path) > 1
}


def spec(key: str) -> KeySpec:
    """The registry entry of "SECTION.Key"; KeyError naming it if unknown."""
    try:
        return _BY_NAME[key]
    except KeyError:
        raise KeyError(f"unknown parameter {key!r}") from None


def keys_of(section: str) -> tuple[KeySpec, ...]:
    """The keys of one section, in file order."""
    return tuple(k for k in KEYS if k.section == section)


# --- the model as a tree of plain values (to apply several changes, then validate) ----

def _walk(obj: Any, path: Sequence[str | int]) -> Any:
    for step in path:
        obj = obj[step] if isinstance(step, int) else getattr(obj, step)
    return obj


def _to_tree(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj):
        return {f.name: _to_tree(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, tuple):
        return [_to_tree(x) for x in obj]
    return obj


def _set_leaf(tree: Any, path: Sequence[str | int], value: Any) -> None:
    for step in path[:-1]:
        tree = tree[step]
    tree[path[-1]] = value


def _from_tree(template: Any, tree: Any, path: tuple[str | int, ...]) -> Any:
    """Rebuild `template`'s type from `tree`, validating every object; a nested
    object's ParameterError is renamed to the full "SECTION.Key"."""
    if dataclasses.is_dataclass(template):
        kwargs = {
            f.name: _from_tree(getattr(template, f.name), tree[f.name], (*path, f.name))
            for f in dataclasses.fields(template)
        }
        cls: type[Any] = type(template)  # an instance's class (is_dataclass also admits classes)
        try:
            return cls(**kwargs)
        except ParameterError as exc:
            if "." in exc.field or path not in _SECTION_OF_PATH:
                raise
            raise ParameterError(f"{_SECTION_OF_PATH[path]}.{exc.field}", exc.reason) from None
    if isinstance(template, tuple):
        if isinstance(tree, tuple):  # a leaf just set (LOGGING.Variables): any length
            return tree
        return tuple(_from_tree(t, x, (*path, i)) for i, (t, x) in enumerate(zip(template, tree)))
    return tree


def iter_keys() -> Iterator[str]:
    """Every parameter name, in file order."""
    return (k.name for k in KEYS)


# --- the built-in settings ------------------------------------------------------------------

def _pi_element(k: float, ti: float) -> ControllerElement:
    """A PI element, and the same PI as a first-order General controller
    (K + K/(Ti s) = (K s + K/Ti) / s), so both families start out equivalent."""
    return ControllerElement(
        pid=PIDParams(K=k, Ti=ti, Td=0.0, integral=True, derivative=False),
        general=GeneralParams(degree=1, s=(k, k / ti, 0.0, 0.0, 0.0), r=(0.0, 0.0, 0.0, 0.0)),
    )


#: An off-diagonal element that contributes nothing until it is set.
_ZERO_ELEMENT = ControllerElement(
    pid=PIDParams(K=0.0, Ti=30.0, integral=True, derivative=False),
    general=GeneralParams(degree=0, s=(0.0, 0.0, 0.0, 0.0, 0.0), r=(0.0, 0.0, 0.0, 0.0)),
)


def from_setting(setting: Setting, pi1: tuple[float, float], pi2: tuple[float, float],
                 *, tsamp_ms: float = 100.0, settling_time: float = 60.0) -> Parameters:
    """Parameters for a physical setting with decentralized PI controllers
    (K, Ti) on the diagonal; the generators' means are the setting's pump voltages
    (normalized), so Manual mode starts at the operating point.  The state feedback
    linearizes at the setting's lower levels with a settling time in s."""
    means = [round(v / FULL_SCALE_V, 6) for v in setting.op.v]
    refs = tuple(
        WaveParams(wave=Wave.SQUARE, mean=m, amplitude=0.05, period=60.0, on=False, seed=1) for m in means
    )
    return Parameters(
        tsamp_ms=tsamp_ms,
        references=refs,  # type: ignore[arg-type]  # one per pump (two); Parameters checks the count
        control=ControlSettings(),
        controllers=(_pi_element(*pi1), _ZERO_ELEMENT, _ZERO_ELEMENT, _pi_element(*pi2)),
        simulation=SimulationSettings.from_setting(setting),
        statefb=StateFeedbackParams(settling_time=settling_time, level1=setting.op.h[0], level2=setting.op.h[1]),
    )


#: The built-in values ("preset"): P-, PI (3.0, 30) and (2.7, 40), 100 ms.
PRESET: Parameters = from_setting(P_MINUS, (3.0, 30.0), (2.7, 40.0))

#: The named settings shipped in params/ (besides default.par, which equals PRESET).
NAMED_SETTINGS: dict[str, Parameters] = {
    "minphase": PRESET,
    # A nonminimum-phase setting needs settling times an order of magnitude longer
    # (Desautel, chapter 5).
    "nonminphase": from_setting(P_PLUS, (1.5, 110.0), (-0.12, 220.0), settling_time=300.0),
}


# --- the other rigs (core.plants; issue 14) -----------------------------------------------

def from_plant(plant: Plant, levels: Sequence[float], means: Sequence[float], *,
               mode: ControlMode = ControlMode.MANUAL,
               pi1: tuple[float, float] | None = None, pi2: tuple[float, float] | None = None,
               tsamp_ms: float = 100.0) -> Parameters:
    """Parameters for another plant (a PLANT section) operated at `levels`.

    means : the generators' means, normalized (pump voltages in Manual, sensor
        references in Automatic); pi1, pi2 : decentralized PI (K, Ti) on the diagonal,
        zero elements where None (the source gives no PI for that rig)
    """
    refs = tuple(
        WaveParams(wave=Wave.SQUARE, mean=round(m, 6), amplitude=0.05, period=60.0, on=False, seed=1)
        for m in means
    )
    return dataclasses.replace(
        PRESET,
        tsamp_ms=tsamp_ms,
        references=refs,  # type: ignore[arg-type]  # one per mean; Parameters checks there are two
        control=ControlSettings(mode=mode),
        controllers=(_ZERO_ELEMENT if pi1 is None else _pi_element(*pi1), _ZERO_ELEMENT, _ZERO_ELEMENT,
                     _ZERO_ELEMENT if pi2 is None else _pi_element(*pi2)),
        process=PlantSpec.of(plant, levels),
    )


def _plant_settings() -> dict[str, Parameters]:
    from quadtank_tui.core.plants import CoupledCascade, CoupledTITO, DesautelQTP

    ctp = CoupledCascade()
    op = ctp.steady_inputs((15.0, None))  # Desautel 2.1.3: x1 = 15 cm, u_e = 6.77 V
    qtp = DesautelQTP()
    tito = CoupledTITO()
    h0 = (0.115, 0.071)  # Murray-Smith's design point; his PI k1 = 5 (1 + 6.2 s)/s, k2 = 0.56 (1 + 10 s)/s
    return {
        "coupled-cascade": from_plant(ctp, op.x, (op.u[0] / ctp.inputs[0].full_scale, 0.0)),
        "desautel-qtp": from_plant(qtp, qtp.steady_state((6.0, 6.0)), (6.0 / qtp.vmax, 6.0 / qtp.vmax)),
        "coupled-tito": from_plant(tito, h0, [y / FULL_SCALE_V for y in tito.output(h0)],
                                   mode=ControlMode.AUTOMATIC, pi1=(31.0, 6.2), pi2=(5.6, 10.0)),  # K = 5 x 6.2, 0.56 x 10
    }


#: The shipped settings of the other rigs (params/coupled-cascade.par, ...).
PLANT_SETTINGS: dict[str, Parameters] = _plant_settings()
