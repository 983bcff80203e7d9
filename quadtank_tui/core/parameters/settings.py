"""The settings dataclasses: one frozen, validated object per `.par` section and
:class:`Parameters`, which composes them and gives access by "SECTION.Key"."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterable, Mapping

from quadtank_tui.core.controllers.general import GeneralParams
from quadtank_tui.core.controllers.matrix import Family, Structure
from quadtank_tui.core.parameters.checks import check_period, enum_value, integer
from quadtank_tui.core.parameters.constants import (
    OP_POINT_MIN,
    POINTS_MAX,
    POINTS_MAX_ORIGINAL,
    REFERENCE_SECTIONS,
    TSAMP,
    TSAMP_MAX_MS,
    TSAMP_MIN_MS,
    ControlMode,
)
from quadtank_tui.core.parameters.keys import KEYS, spec
from quadtank_tui.core.parameters.tree import replaced, walk
from quadtank_tui.core.controllers.pid import PIDParams
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.plants.johansson import (
    Levels, PlantParams, Setting, area_from_diameter, diameter_from_area, levels_to_normalized,
    outlet_from_time_constant, time_constant,
)
from quadtank_tui.core.plants import Plant, QuadTank
from quadtank_tui.core.plants.spec import PlantSpec, check_quadtank_effects
from quadtank_tui.core.controllers.signals import WaveParams
from quadtank_tui.core.controllers.mpc.settings import MPCSettings
from quadtank_tui.core.controllers.statefb.settings import StateFeedbackParams
from quadtank_tui.core.ranges import ParameterError, check_range

#: Each key's place in the model (KEYS is in file order, the model's order).
_POSITION = {k.name: i for i, k in enumerate(KEYS)}


@dataclass(frozen=True)
class ControlSettings:
    """CONTROL section: mode and the controller matrix's type."""

    mode: ControlMode = ControlMode.MANUAL
    family: Family = Family.PID
    structure: Structure = Structure.DECENTRALIZED

    def __post_init__(self) -> None:
        for attr, key, enum in (("mode", "Mode", ControlMode), ("family", "Type", Family),
                                ("structure", "Structure", Structure)):
            object.__setattr__(self, attr, enum_value(key, enum, getattr(self, attr)))


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
    #: The real-rig effects that are on, (name, value) (core.plants.quadtank:
    #: spill3, vmin1, ysat2, ...); a `.par` file holds them in a PLANT section of
    #: Kind quadtank, written only when one is on.
    effects: tuple[tuple[str, float], ...] = ()

    def __post_init__(self) -> None:
        if self.effects:
            check_quadtank_effects(self.effects)
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
        h = setting.op.x
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
    `.log`), and the logged columns in order.

    Which names a file name and the columns may be is the files' business
    (quadtank_tui.files.names.check_names, applied wherever they come in); here
    they are text."""

    points: int = POINTS_MAX_ORIGINAL
    log_file: str = "data"
    variables: tuple[str, ...] = ("y1", "y2", "u1", "u2")

    def __post_init__(self) -> None:
        integer("Points", self.points, 1, POINTS_MAX)
        if not isinstance(self.log_file, str) or not self.log_file:
            raise ParameterError("LogFile", f"must be a file name, got {self.log_file!r}")
        if not isinstance(self.variables, tuple) or not self.variables or not all(
                isinstance(v, str) for v in self.variables):
            raise ParameterError("Variables", f"must be one or more names, got {self.variables!r}")


@dataclass(frozen=True)
class PlotSettings:
    """PLOTS section: the plot type of the upper and lower trend (thesis Fig. 35),
    as text with single spaces; the list of plot types is the screens'
    (quadtank_tui.files.names.PLOT_TYPES, checked wherever a value comes in)."""

    upper: str = "u1 u2"
    lower: str = "y1 y2 ref1 ref2"

    def __post_init__(self) -> None:
        for attr, key in (("upper", "Upper"), ("lower", "Lower")):
            value = getattr(self, attr)
            if not isinstance(value, str) or not value.split():
                raise ParameterError(key, f"must be a plot type, got {value!r}")
            object.__setattr__(self, attr, " ".join(value.split()))


@dataclass(frozen=True)
class Parameters:
    """Every parameter of the interface (one `.par` file's worth).

    tsamp_ms : sampling time of controllers and simulation, ms (kept in the file's
        unit so a saved value reloads exactly; :attr:`tsamp` gives seconds)
    references : generators 1 and 2 (u1/u2 in Manual, ref1/ref2 in Automatic)
    controllers : elements 11, 12, 21, 22 (CONTROLLER ONE..FOUR)
    statefb : the state-feedback controller's settings (STATE FEEDBACK; files
        without the section get the defaults)
    mpc : the model predictive controller's settings (MPC; defaults without it)
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
    mpc: MPCSettings = MPCSettings()
    extra: tuple[tuple[str, str, str], ...] = ()
    process: PlantSpec | None = None

    def __post_init__(self) -> None:
        check_range(TSAMP, self.tsamp_ms, TSAMP_MIN_MS, TSAMP_MAX_MS)
        if len(self.references) != 2:
            raise ParameterError("REFERENCE ONE", f"two references are needed, got {len(self.references)}")
        if len(self.controllers) != 4:
            raise ParameterError("CONTROLLER ONE", f"four controller elements are needed, got {len(self.controllers)}")
        for section, ref in zip(REFERENCE_SECTIONS, self.references):
            check_period(section, ref, self.tsamp_ms)

    @property
    def tsamp(self) -> float:
        """Sampling time, s."""
        return self.tsamp_ms / 1000.0

    # --- generic access by "SECTION.Key" ----------------------------------------

    def get(self, key: str) -> Any:
        """The value of parameter `key` ("SECTION.Key"); KeyError if unknown."""
        return walk(self, spec(key).path)

    def values(self) -> dict[str, Any]:
        """Every parameter by key, in file order."""
        return {k.name: walk(self, k.path) for k in KEYS}

    def with_value(self, key: str, value: Any) -> Parameters:
        """A copy with one parameter changed (validated; ParameterError names `key`)."""
        return self.with_values({key: value})

    def with_values(self, changes: Mapping[str, Any]) -> Parameters:
        """A copy with several parameters changed at once.

        Applied together, then validated together: a pair of values that is only
        valid jointly (a sampling time and a period) can be set in one call.
        """
        coerced = []
        for key, value in changes.items():
            k = spec(key)
            coerced.append((k, k.coerce(value)))
        # Rebuilt in the model's order whatever the caller's: of several bad values,
        # the one refused is the first in the file (a .par's keys come in its order).
        coerced.sort(key=lambda kv: _POSITION[kv[0].name])
        return replaced(self, {k.path: value for k, value in coerced})

    # `default` is always given (the preset, or a params folder's default.par):
    # presets.py builds PRESET from these classes, so this module never imports it.
    def with_defaults(self, keys: Iterable[str], default: Parameters) -> Parameters:
        """A copy with `keys` back at their values in `default` (a window's Default
        button: e.g. ``p.with_defaults((k.name for k in keys_of("CONTROLLER ONE")), PRESET)``)."""
        return self.with_values({key: default.get(key) for key in keys})

    def modified_keys(self, default: Parameters) -> frozenset[str]:
        """Keys whose value differs from `default` (e.g. the built-in PRESET)."""
        base = default.values()
        return frozenset(k for k, v in self.values().items() if v != base[k])

    def is_modified(self, key: str, default: Parameters) -> bool:
        """Whether `key` differs from its value in `default` (the UI greys modified values)."""
        return self.get(key) != default.get(key)

    def quadtank_constants(self) -> PlantParams:
        """The quadruple tank's constants of the SIMULATION section (see
        SimulationSettings.plant), whatever plant is in use: only for code that
        works on the quadruple tank alone (after checking ``process is None``).
        The plant in use is :meth:`process_plant`; there is deliberately no
        ``plant()`` here, so the two cannot be confused."""
        return self.simulation.plant()

    def operating_levels(self) -> Levels:
        """Operating levels, cm."""
        return self.simulation.operating_levels()

    def process_plant(self) -> Plant:
        """The plant in use, through the plant interface (core.plants)."""
        if self.process is not None:
            return self.process.plant()
        return QuadTank(self.quadtank_constants(), **dict(self.simulation.effects))

    def process_levels(self) -> tuple[float, ...]:
        """Operating levels of the plant in use, in its own length unit."""
        return tuple(self.operating_levels()) if self.process is None else self.process.levels
