"""`.par` parameter files: read what the original wrote, write the complete format.

Reading is all-or-nothing: the whole file is parsed and validated into a new
:class:`Parameters` before anything is returned, so a bad file raises
:class:`ParFileError` (naming file, line and key) and the caller's parameters are
never half-changed.  Missing sections/keys take the `base` values; unknown ones are
kept (and written back on save) and reported as warnings.

Numbers are written `%f` (TSamp `%.4f`) as the original did.  A value `%f` cannot
carry exactly (more than six decimals, e.g. a time constant computed from a
diameter) is written with the shortest decimal that reads back to the same double,
still in positional notation: every saved file reloads to exactly the parameters
that were saved, and values a user types look as they always did.

:class:`ParStore` is the `params/` folder of the Parameters window: names, not
paths; `default` and `preset` reserved.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from datetime import datetime
from decimal import Decimal
from pathlib import Path
from typing import Any

from quadtank_tui.core.parameters import (
    KEYS,
    PRESET,
    REFERENCE_SECTIONS,
    SECTIONS,
    TSAMP,
    Kind,
    KeySpec,
    Parameters,
    keys_of,
)
from quadtank_tui.core.plants.spec import SECTION as PLANT_SECTION
from quadtank_tui.core.plants.spec import KIND_KEY, PlantSpec, quadtank_effects, spec_from_entries
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.files.atomic import atomic_write_text
from quadtank_tui.files.names import check_file_name, check_names
from quadtank_tui.files.regular import read_regular
from quadtank_tui.files.stamp import format_stamp

HEADER = "% TANK PAR-file"
SUFFIX = ".par"
#: Names the normal save refuses, and why.
RESERVED = {
    "default": "'default' is reserved: it holds everyone's defaults and is not overwritten by a normal "
    "save (copy a saved file to default.par to change them)",
    "preset": "'preset' is reserved: it names the built-in values, which no file replaces",
}
#: A parameter file is a few kB; anything much larger is not one.
MAX_BYTES = 1_000_000

_SECTION_LINE = re.compile(r"[A-Z][A-Z ]*[A-Z]")
_ENTRY_LINE = re.compile(r"(\S+)\s+(\S.*)")
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")
_SPEC = {(k.section, k.key.lower()): k for k in KEYS}


class ParFileError(ValueError):
    """A `.par` file refused as a whole; says which file, line and key, and why."""

    def __init__(self, file: str, reason: str, line: int | None = None, key: str | None = None) -> None:
        where = file if line is None else f"{file}, line {line}"
        super().__init__(f"{where}: {key + ': ' if key else ''}{reason}")
        self.file = file
        self.line = line
        self.key = key
        self.reason = reason


@dataclass(frozen=True)
class ParRead:
    """A file's parameters and what the reader wants the user to know."""

    params: Parameters
    warnings: tuple[str, ...] = ()


# --- reading --------------------------------------------------------------------------

def parse_par(data: bytes | str, *, name: str = "<par>", base: Parameters = PRESET) -> ParRead:
    """Parse `.par` content; values the file does not set keep `base`'s.

    Raises ParFileError for anything that is not a valid parameter file.
    """
    lines = _text_lines(data, name)
    changes: dict[str, Any] = {}
    where: dict[str, int] = {}
    extra: list[tuple[str, str, str]] = []
    warnings: list[str] = []
    seen: dict[tuple[str, str], int] = {}
    section: str | None = None
    any_section = False
    plant_entries: dict[str, str] = {}
    plant_lines: dict[str, int] = {}
    for no, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line:
            section = None
            continue
        if line.startswith("%"):
            if no == 1 and line.upper().startswith("% TANK LOG"):
                raise ParFileError(name, "this is a .log data file, not a .par parameter file", no)
            continue
        if not line.replace("\t", " ").isprintable():
            raise ParFileError(name, "binary or control characters: not a parameter file", no)
        if _SECTION_LINE.fullmatch(line):
            section = " ".join(line.split())
            any_section = True
            if section not in SECTIONS and section != PLANT_SECTION:
                warnings.append(f"{name}, line {no}: unknown section {section!r} (kept, not used)")
            continue
        m = _ENTRY_LINE.fullmatch(line)
        if m is None:
            raise ParFileError(name, "malformed line: expected 'Key value'", no, line[:40])
        key, text = m.group(1), m.group(2)
        if section is None:
            raise ParFileError(name, "entry outside any section (a section name in capitals must come first)", no, key)
        if section == PLANT_SECTION:
            if key in plant_lines:
                raise ParFileError(name, f"duplicate key (first set on line {plant_lines[key]})", no, f"{section}.{key}")
            plant_entries[key], plant_lines[key] = text, no
            continue
        spec = _SPEC.get((section, key.lower()))
        if spec is not None:
            key = spec.key  # keys match whatever their case ("tsamp"): no two differ only by it
        if (section, key) in seen:
            raise ParFileError(name, f"duplicate key (first set on line {seen[section, key]})", no, f"{section}.{key}")
        seen[section, key] = no
        if spec is None:
            extra.append((section, key, text))
            if section in SECTIONS:
                warnings.append(f"{name}, line {no}: unknown key {key!r} in {section} (kept, not used)")
            continue
        changes[spec.name] = _parse_value(spec, text, name, no)
        where[spec.name] = no
    if not any_section:
        raise ParFileError(name, "no section found: not a parameter file (empty or truncated?)", 1 if not lines else len(lines))
    try:
        params = base.with_values(check_names(changes))
    except ParameterError as exc:
        line_no = where.get(exc.field) or _related_line(exc.field, where)
        raise ParFileError(name, exc.reason, line_no, exc.field) from None
    # No PLANT section is the quadruple tank, whatever the base: an old file always
    # loads as what it was written for.
    process = _read_plant(plant_entries, plant_lines, name) if plant_lines else None
    if process is None and plant_lines:  # Kind quadtank: the real-rig effects (checked by _read_plant)
        effects = quadtank_effects(plant_entries, lambda k, t: float(t))
        params = dataclasses.replace(params, simulation=dataclasses.replace(params.simulation, effects=effects))
    return ParRead(dataclasses.replace(params, extra=tuple(extra), process=process), tuple(warnings))


def _read_plant(entries: dict[str, str], lines: dict[str, int], name: str) -> PlantSpec | None:
    """The PLANT section (core.plants.spec); errors name its line and key."""
    def number(key: str, text: str) -> float:
        if not _NUMBER.fullmatch(text):
            raise ParFileError(name, f"not a number: {text[:40]!r}", lines[key], f"{PLANT_SECTION}.{key}")
        return float(text)

    try:
        return spec_from_entries(entries, number)
    except ParameterError as exc:
        key = exc.field.split(".", 1)[1]
        line = lines.get(key, min(lines.values()))
        raise ParFileError(name, exc.reason, line, exc.field) from None


def read_par(path: Path | str, *, base: Parameters = PRESET) -> ParRead:
    """Read a `.par` file (see :func:`parse_par`); OS errors become ParFileError."""
    path = Path(path)
    try:
        data = read_regular(path, MAX_BYTES)
    except FileNotFoundError:
        raise ParFileError(str(path), "no such file") from None
    except OSError as exc:
        raise ParFileError(str(path), f"cannot read: {exc.strerror or exc}") from None
    if len(data) > MAX_BYTES:
        raise ParFileError(str(path), f"larger than {MAX_BYTES} bytes: not a parameter file")
    return parse_par(data, name=str(path), base=base)


def _text_lines(data: bytes | str, name: str) -> list[str]:
    """Lines without their ends (LF or CRLF), refusing binary data by line."""
    if isinstance(data, bytes):
        nul = data.find(b"\x00")
        try:
            text = data.decode("utf-8")
            bad = None
        except UnicodeDecodeError as exc:
            bad = exc.start
        if nul >= 0 and (bad is None or nul < bad):
            raise ParFileError(name, "binary data (NUL byte): not a parameter file", data[:nul].count(b"\n") + 1)
        if bad is not None:
            raise ParFileError(name, "not a text file (undecodable byte)", data[:bad].count(b"\n") + 1)
        data = text
    data = data.removeprefix("\ufeff")  # the byte-order mark some Windows editors write
    return [ln[:-1] if ln.endswith("\r") else ln for ln in data.split("\n")]


def _parse_value(spec: KeySpec, text: str, name: str, no: int) -> Any:
    if spec.kind in (Kind.NUMBER, Kind.INTEGER, Kind.FLAG):
        if not _NUMBER.fullmatch(text):
            raise ParFileError(name, f"not a number: {text[:40]!r}", no, spec.name)
        x = float(text)
        if x != x or x in (float("inf"), float("-inf")):
            raise ParFileError(name, f"number too large: {text[:40]!r}", no, spec.name)
        return x
    return text


def _related_line(key: str, where: dict[str, int]) -> int | None:
    """A period refused because of the sampling time: point at TSamp if the file
    set that and not the period."""
    if key.endswith(".Period") and key.split(".")[0] in REFERENCE_SECTIONS:
        return where.get(TSAMP)
    return None


# --- writing --------------------------------------------------------------------------

def format_number(x: float, fmt: str = "%f") -> str:
    """`fmt % x` if that reads back to exactly `x`, else the shortest exact decimal
    (positional, never an exponent, so any `%f` reader still understands it)."""
    text = fmt % x
    if float(text) == x:
        return text
    return format(Decimal(repr(float(x))), "f")


def format_value(spec: KeySpec, value: Any) -> str:
    """A parameter's value as the file writes it."""
    if spec.kind is Kind.NUMBER:
        return format_number(value, "%.4f" if spec.name == TSAMP else "%f")
    if spec.kind in (Kind.INTEGER, Kind.FLAG):
        return "%d" % int(value)
    if spec.kind is Kind.NAMES:
        return " ".join(value)
    return str(getattr(value, "value", value))


def format_par(params: Parameters, created: datetime) -> str:
    """The complete file: every section and key, then the kept unknown entries."""
    out = [HEADER, f"% Created on: {format_stamp(created)}"]
    extra_sections = list(dict.fromkeys(s for s, _, _ in params.extra if s not in SECTIONS))
    for section in (*SECTIONS, *extra_sections):
        out.append("")
        out.append(section)
        out += [f"{k.key} {format_value(k, params.get(k.name))}" for k in keys_of(section)]
        out += [f"{key} {text}" for s, key, text in params.extra if s == section]
    if params.process is not None:  # written only for another plant: quadtank files stay as they were
        out += ["", PLANT_SECTION]
        out += [f"{k} {v if isinstance(v, str) else format_number(v)}" for k, v in params.process.file_entries()]
    elif params.simulation.effects:  # the quadruple tank's real-rig effects, only when one is on
        out += ["", PLANT_SECTION, f"{KIND_KEY} quadtank"]
        out += [f"{k} {format_number(v)}" for k, v in params.simulation.effects]
    return "\n".join(out) + "\n"


def write_par(path: Path | str, params: Parameters, *, created: datetime | None = None) -> Path:
    """Save atomically: an interrupted save leaves the previous file as it was."""
    return atomic_write_text(path, format_par(params, created or datetime.now()), encoding="utf-8")


# --- the params/ folder -------------------------------------------------------------------

class ParStore:
    """Named parameter files in one folder (the original's application directory).

    `load("preset")` gives the built-in values; `load("default")` rereads
    `default.par` (the built-ins, with a warning, if it is missing or broken).
    Neither name can be saved through :meth:`save`: the defaults are changed by an
    administrator copying a file to `default.par`, as in the original.
    """

    def __init__(self, folder: Path | str) -> None:
        self.folder = Path(folder)

    def names(self) -> list[str]:
        """Names of the saved settings (file names without `.par`), sorted."""
        if not self.folder.is_dir():
            return []
        return sorted(p.stem for p in self.folder.glob(f"*{SUFFIX}") if not p.name.startswith("."))

    def path_of(self, name: str) -> Path:
        """The file a name stands for; ParFileError if the name is not a plain name."""
        stem = _stem(name)
        try:
            check_file_name(stem, "name")
        except ParameterError as exc:
            raise ParFileError(str(name), exc.reason.replace("must be", "a parameter file name must be")) from None
        return self.folder / f"{stem}{SUFFIX}"

    def exists(self, name: str) -> bool:
        """Whether saving under `name` would overwrite a file (ask first)."""
        return self.path_of(name).exists()

    def defaults(self) -> ParRead:
        """What the interface starts with: `default.par`, else the built-ins."""
        path = self.folder / f"default{SUFFIX}"
        if not path.exists():
            return ParRead(PRESET, (f"{path} not found: using the built-in (preset) values",))
        try:
            return read_par(path, base=PRESET)
        except ParFileError as exc:
            return ParRead(PRESET, (f"{exc}; using the built-in (preset) values instead",))

    def load(self, name: str, defaults: ParRead | None = None) -> ParRead:
        """The parameters saved under `name`; missing values take the defaults
        (`defaults`: `default.par` as already read, to read it only once)."""
        stem = _stem(name)
        if stem.lower() == "preset":
            return ParRead(PRESET)
        if defaults is None:
            defaults = self.defaults()
        if stem.lower() == "default":
            return defaults
        path = self.path_of(stem)
        read = read_par(path, base=defaults.params)
        return ParRead(read.params, defaults.warnings + read.warnings)

    def save(self, name: str, params: Parameters, *, created: datetime | None = None) -> Path:
        """Write `params` under `name` (atomically); the reserved names are refused."""
        stem = _stem(name)
        if stem.lower() in RESERVED:
            raise ParFileError(stem, RESERVED[stem.lower()])
        path = self.path_of(stem)
        self.folder.mkdir(parents=True, exist_ok=True)
        return write_par(path, params, created=created)

    def save_default(self, params: Parameters, *, created: datetime | None = None) -> Path:
        """Replace `default.par`, everyone's defaults (atomically).  Only for an
        administrator: the caller checked the role (session.roles), since this
        layer knows nothing of users."""
        self.folder.mkdir(parents=True, exist_ok=True)
        return write_par(self.folder / f"default{SUFFIX}", params, created=created)


def _stem(name: str) -> str:
    name = name.strip()
    return name[: -len(SUFFIX)] if name.lower().endswith(SUFFIX) else name
