"""Which plant the parameters describe: a `.par` file's PLANT section as a value.

The quadruple tank keeps living in the SIMULATION section (old files are unchanged,
and have no PLANT section); another plant is named by its kind, every physical
constant by the name its class uses, and the operating levels in its own length
unit::

    PLANT
    Kind coupled-cascade
    alpha1 0.009791
    ...
    Level1 15.000000
    Level2 14.727394

A refused value raises ParameterError naming "PLANT.<key>".

The same keys, "PLANT.alpha1", "PLANT.Level1", ..., change the plant in use while
it runs (Setup's plant window, a script's `set:`): :meth:`PlantSpec.with_values`
applies them all or none.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

from quadtank_tui.core.plants.common import PlantError
from quadtank_tui.core.plants import KINDS, Plant, QuadTank, make_plant
from quadtank_tui.core.ranges import ParameterError, check_number

SECTION = "PLANT"
KIND_KEY = "Kind"
#: What a parameter key of the plant in use starts with ("PLANT.alpha1").
PREFIX = SECTION + "."


def level_key(i: int) -> str:
    """The key of operating level i (0-based): Level1, Level2, ..."""
    return f"Level{i + 1}"


@dataclass(frozen=True)
class PlantSpec:
    """kind, its constants (every one, in the class's order) and operating levels."""

    kind: str
    values: tuple[tuple[str, float], ...]
    levels: tuple[float, ...]

    def __post_init__(self) -> None:
        if self.kind not in KINDS or self.kind == "quadtank":
            known = ", ".join(k for k in KINDS if k != "quadtank")
            raise ParameterError(f"{SECTION}.{KIND_KEY}", f"must be one of quadtank, {known}; got {self.kind!r}")
        for name, value in self.values:
            check_number(f"{SECTION}.{name}", value)
        try:
            plant = make_plant(self.kind, dict(self.values))
        except PlantError as exc:
            words = str(exc).split()
            field = words[0] if words and words[0] in KINDS[self.kind]().values() else KIND_KEY
            raise ParameterError(f"{SECTION}.{field}", str(exc)) from None
        states = plant.states
        if len(self.levels) != len(states):
            raise ParameterError(f"{SECTION}.{level_key(len(self.levels))}",
                                 f"a {self.kind} plant has {len(states)} operating levels, got {len(self.levels)}")
        for i, (x, s) in enumerate(zip(self.levels, states)):
            check_number(f"{SECTION}.{level_key(i)}", x)
            if not s.lo < x <= s.hi:
                raise ParameterError(f"{SECTION}.{level_key(i)}",
                                     f"operating level {s.name} must be in ({s.lo:g}, {s.hi:g}] {s.unit}, got {x:g}")

    @classmethod
    def of(cls, plant: Plant, levels: Sequence[float]) -> PlantSpec:
        """The section for `plant` operated at `levels`."""
        return cls(plant.kind, tuple((k, float(v)) for k, v in plant.values().items()),
                   tuple(float(x) for x in levels))

    def plant(self) -> Plant:
        return make_plant(self.kind, dict(self.values))

    def get(self, key: str) -> float:
        """A constant or an operating level by its key (without "PLANT.")."""
        found = dict(self.entries()).get(key)
        if found is None or key == KIND_KEY:
            raise ParameterError(f"{SECTION}.{key}", f"a {self.kind} plant has no value {key!r}")
        return float(found)

    def with_values(self, changes: Mapping[str, float]) -> PlantSpec:
        """A copy with constants and operating levels changed by key ("alpha1",
        "Level1"; "PLANT." in front is allowed), validated together: all or none,
        ParameterError naming the key otherwise."""
        values = dict(self.values)
        levels = list(self.levels)
        level_keys = [level_key(i) for i in range(len(levels))]
        for raw, value in changes.items():
            key = raw.removeprefix(PREFIX)
            number = check_number(f"{SECTION}.{key}", value)
            if key in values:
                values[key] = number
            elif key in level_keys:
                levels[level_keys.index(key)] = number
            else:
                raise ParameterError(f"{SECTION}.{key}", f"a {self.kind} plant has no value {key!r} "
                                     f"(it has {', '.join(values)}, {', '.join(level_keys)})")
        given = {raw.removeprefix(PREFIX) for raw in changes}
        spec = PlantSpec(self.kind, tuple(values.items()), tuple(levels))
        return spec.with_following_levels() if not given & set(level_keys[spec.free_levels:]) else spec

    @property
    def free_levels(self) -> int:
        """How many operating levels are chosen (one per pump: x1 of the cascade,
        h1, h2 of a quadruple tank); the others follow from them at steady state."""
        return len(self.plant().inputs)

    def with_following_levels(self) -> PlantSpec:
        """The levels beyond the chosen ones set to the steady state the chosen ones
        give (x2 = (alpha1 / alpha2)^2 x1 on the cascade, Desautel 2.1.6); unchanged
        when there is none (the pumps cannot hold the chosen levels)."""
        k = self.free_levels
        if k >= len(self.levels):
            return self
        try:
            x = self.plant().steady_inputs(list(self.levels[:k]) + [None] * (len(self.levels) - k)).x
        except PlantError:
            return self
        return PlantSpec(self.kind, self.values, self.levels[:k] + tuple(float(v) for v in x[k:]))

    def entries(self) -> list[tuple[str, float | str]]:
        """(key, value) in file order."""
        return [(KIND_KEY, self.kind), *self.values,
                *((level_key(i), x) for i, x in enumerate(self.levels))]

    def file_entries(self) -> list[tuple[str, float | str]]:
        """What a `.par` file writes: the entries less the real-rig effects that are
        off (Plant.effect_names at 0), so a file without them reads back the same."""
        off = {k for k in KINDS[self.kind].effect_names if dict(self.values).get(k) == 0.0}
        return [(k, v) for k, v in self.entries() if k not in off]


def spec_from_entries(entries: dict[str, str], number: Callable[[str, str], float]) -> PlantSpec | None:
    """Build the spec from a PLANT section's raw entries; None for `Kind quadtank`
    (the SIMULATION section holds it).  Keys missing from the file take the plant's
    defaults; `number(key, text)` parses a value (the file reader's, with its line)."""
    kind = entries.get(KIND_KEY)
    if kind is None:
        raise ParameterError(f"{SECTION}.{KIND_KEY}", "the PLANT section must name the plant (Kind ...)")
    kind = kind.strip()
    if kind == "quadtank":
        quadtank_effects(entries, number)
        return None
    if kind not in KINDS:
        raise ParameterError(f"{SECTION}.{KIND_KEY}", f"must be one of {', '.join(KINDS)}; got {kind!r}")
    defaults = KINDS[kind]().values()
    n = len(KINDS[kind]().states)
    levels_keys = [level_key(i) for i in range(n)]
    unknown = [k for k in entries if k not in defaults and k not in levels_keys and k != KIND_KEY]
    if unknown:
        raise ParameterError(f"{SECTION}.{unknown[0]}", f"a {kind} plant has no constant {unknown[0]!r} "
                             f"(it has {', '.join(defaults)}, {', '.join(levels_keys)})")
    missing = [k for k in levels_keys if k not in entries]
    if missing:
        raise ParameterError(f"{SECTION}.{missing[0]}", "every operating level must be given")
    values = tuple((k, number(k, entries[k]) if k in entries else float(v)) for k, v in defaults.items())
    return PlantSpec(kind, values, tuple(number(k, entries[k]) for k in levels_keys))



def quadtank_effects(entries: dict[str, str], number: Callable[[str, str], float]) -> tuple[tuple[str, float], ...]:
    """The real-rig effects a PLANT section of `Kind quadtank` sets (its constants
    live in SIMULATION), in the plant's order; ParameterError names the key."""
    names = QuadTank.effect_names
    for key in entries:
        if key != KIND_KEY and key not in names:
            raise ParameterError(f"{SECTION}.{key}", "the quadruple tank's values live in SIMULATION; its PLANT "
                                 f"section holds only the real-rig effects ({', '.join(names)})")
    values = tuple((k, v) for k in names if k in entries and (v := number(k, entries[k])) != 0.0)
    check_quadtank_effects(values)
    return values


def check_quadtank_effects(values: Sequence[tuple[str, float]]) -> None:
    """ParameterError("PLANT.<key>") unless `values` are valid effects of a quadruple tank."""
    for name, value in values:
        if name not in QuadTank.effect_names:
            raise ParameterError(f"{SECTION}.{name}", f"a quadtank has no effect {name!r} "
                                 f"(it has {', '.join(QuadTank.effect_names)})")
        check_number(f"{SECTION}.{name}", value)
    try:
        QuadTank().with_values(**dict(values))
    except PlantError as exc:
        field = str(exc).split()[0]
        raise ParameterError(f"{SECTION}.{field}", str(exc)) from None
