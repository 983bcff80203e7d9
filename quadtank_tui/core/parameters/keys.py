"""The key table: every parameter's `.par` section and key, kind and place in the
model, and how a raw value is coerced to its Python type.

The names ``"SECTION.Key"`` are the public handle of the model: the file reader,
the scripts and the windows all go through :func:`spec`, so a parameter cannot be
known to one and missing from another.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any, Iterator

from quadtank_tui.core.controllers.matrix import Family, Structure
from quadtank_tui.core.controllers.mpc.settings import DISTURBANCE_MODELS
from quadtank_tui.core.parameters.checks import whole
from quadtank_tui.core.parameters.constants import (
    CONTROLLER_SECTIONS,
    MAX_ABS,
    REFERENCE_SECTIONS,
    MPC_SECTION,
    STATEFB_SECTION,
    ControlMode,
)
from quadtank_tui.core.controllers.signals import Wave
from quadtank_tui.core.ranges import ParameterError, check_number


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
    return whole(k.key, value)


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
        # The plot types are the screens' (quadtank_tui.files.names.PLOT_TYPES): text here.
        KeySpec("PLOTS", "Upper", Kind.NAME, ("plots", "upper")),
        KeySpec("PLOTS", "Lower", Kind.NAME, ("plots", "lower")),
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
    mpc: tuple[str | int, ...] = ("mpc",)
    keys += [
        KeySpec(MPC_SECTION, "Horizon", Kind.INTEGER, (*mpc, "horizon")),
        KeySpec(MPC_SECTION, "Step", Kind.NUMBER, (*mpc, "step")),
        KeySpec(MPC_SECTION, "ControlHorizon", Kind.INTEGER, (*mpc, "control_horizon")),
        KeySpec(MPC_SECTION, "OutputWeight", Kind.NUMBER, (*mpc, "output_weight")),
        KeySpec(MPC_SECTION, "InputWeight", Kind.NUMBER, (*mpc, "input_weight")),
        KeySpec(MPC_SECTION, "RateWeight", Kind.NUMBER, (*mpc, "rate_weight")),
        KeySpec(MPC_SECTION, "RateLimit", Kind.NUMBER, (*mpc, "rate_limit")),
        KeySpec(MPC_SECTION, "LevelMargin", Kind.NUMBER, (*mpc, "level_margin")),
        KeySpec(MPC_SECTION, "Preview", Kind.FLAG, (*mpc, "preview")),
        KeySpec(MPC_SECTION, "Disturbance", Kind.CHOICE, (*mpc, "disturbance"), DISTURBANCE_MODELS),
        KeySpec(MPC_SECTION, "Measured", Kind.NAME, (*mpc, "measured")),
        KeySpec(MPC_SECTION, "SlackWeight", Kind.NUMBER, (*mpc, "slack_weight")),
    ]
    return tuple(keys)


#: Every parameter, in the order a `.par` file lists them.
KEYS: tuple[KeySpec, ...] = _build_keys()
_BY_NAME = {k.name: k for k in KEYS}
#: Section names in file order.
SECTIONS: tuple[str, ...] = tuple(dict.fromkeys(k.section for k in KEYS))
#: Which section owns each object of the model (for naming errors of nested types).
SECTION_OF_PATH: dict[tuple[str | int, ...], str] = {
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


def iter_keys() -> Iterator[str]:
    """Every parameter name, in file order."""
    return (k.name for k in KEYS)
