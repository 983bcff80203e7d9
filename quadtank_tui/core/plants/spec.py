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
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

from quadtank_tui.core.plant import PlantError
from quadtank_tui.core.plants import KINDS, Plant, make_plant
from quadtank_tui.core.validation import ParameterError, check_number

SECTION = "PLANT"
KIND_KEY = "Kind"


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

    def entries(self) -> list[tuple[str, float | str]]:
        """(key, value) in file order."""
        return [(KIND_KEY, self.kind), *self.values,
                *((level_key(i), x) for i, x in enumerate(self.levels))]


def spec_from_entries(entries: dict[str, str], number: Callable[[str, str], float]) -> PlantSpec | None:
    """Build the spec from a PLANT section's raw entries; None for `Kind quadtank`
    (the SIMULATION section holds it).  Keys missing from the file take the plant's
    defaults; `number(key, text)` parses a value (the file reader's, with its line)."""
    kind = entries.get(KIND_KEY)
    if kind is None:
        raise ParameterError(f"{SECTION}.{KIND_KEY}", "the PLANT section must name the plant (Kind ...)")
    kind = kind.strip()
    if kind == "quadtank":
        extra = [k for k in entries if k != KIND_KEY]
        if extra:
            raise ParameterError(f"{SECTION}.{extra[0]}", "the quadruple tank's values live in SIMULATION")
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

