"""Exercise files: one YAML file per exercise a teacher writes (docs/exercises.md).

    title: "P-: decentralized PI"
    text: |
      What the student reads.
    par: ../minphase.par            # relative to this file, or a name in params/
    runs_on: either                 # simulator | rig | either
    may_change:
      types: [PID]                  # CONTROL.Type values the student may use
      keys: ["CONTROLLER ONE.K", "CONTROLLER ONE.Ti"]
      sections: ["CONTROLLER FOUR"] # every key of these sections
    experiment:
      script: pminus-step.yaml      # or: own_run: {step: {"REFERENCE ONE.Mean": 0.1}}
      duration: 1200
    time_limit: 2700                # s the student has (optional)
    identify: {method: oe}          # for the model requirements (optional)
    requirements:
      - overshoot: {loop: 1, max: 10}
      - settling_time: {loop: 1, band: 0.02, max: 90}
    reference: reference/pminus.par # the reference solution (optional)
    teacher: |
      A note for the teacher.

Everything is checked when the file is read; a problem is an ExerciseError whose
message is one line naming the file and the line.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from quadtank_tui.core.exercise.requirements import KINDS, WRITTEN, Requirement
from quadtank_tui.core.parameters import spec
from quadtank_tui.core.parameters.keys import SECTIONS
from quadtank_tui.core.ranges import is_finite_number
from quadtank_tui.files.regular import read_regular
from quadtank_tui.files.yamltext import MAX_BYTES, key_lines, parse_yaml

RUNS_ON = ("simulator", "rig", "either")
TYPES = ("PID", "General", "State feedback", "MPC")
TOP_KEYS = ("title", "text", "par", "runs_on", "may_change", "experiment", "time_limit", "identify",
            "requirements", "reference", "teacher")
IDENTIFY_METHODS = ("oe", "step", "arx", "n4sid")
ELEMENTS = ("11", "12", "21", "22")
#: The start of the reason a YAML file that is not a mapping (a script) is refused with.
NOT_A_MAPPING = "an exercise is a mapping"
#: A run's length: a long lab session at most (8 h).
MAX_DURATION = 8 * 3600.0


class ExerciseError(ValueError):
    """A refused exercise file: "FILE, line N: reason"."""

    def __init__(self, file: str, reason: str, line: int | None = None) -> None:
        super().__init__(f"{file}, line {line}: {reason}" if line else f"{file}: {reason}")
        self.file, self.reason, self.line = file, reason, line


@dataclass(frozen=True)
class OwnRun:
    """The student's own run must hold this event: a step of `key` by `delta`
    (a reference mean) while the loops are in Automatic."""

    key: str
    delta: float

    @property
    def loop(self) -> int:
        return 1 if self.key.startswith("REFERENCE ONE") else 2


@dataclass(frozen=True)
class Experiment:
    """`script`: the exercise's experiment (a path), or None with `own_run`: the
    student's own run (their script, or their session in the TUI)."""

    duration: float
    script: Path | None = None
    own_run: OwnRun | None = None


@dataclass(frozen=True)
class Identify:
    method: str = "oe"
    order: int | None = None
    zeros: int = 0


@dataclass(frozen=True)
class Exercise:
    path: Path
    digest: str  # sha256 of the file's bytes
    title: str
    text: str
    par: str  # a path (made absolute from the file's folder) or a name in params/
    runs_on: str
    types: tuple[str, ...]
    keys: tuple[str, ...]
    sections: tuple[str, ...]
    experiment: Experiment
    requirements: tuple[Requirement, ...]
    time_limit: float | None = None
    identify: Identify = field(default_factory=Identify)
    reference: Path | None = None
    teacher: str = ""

    @property
    def id(self) -> str:
        """The exercise's name: its file's stem (pminus-pi)."""
        return self.path.stem

    def may_change(self, key: str) -> bool:
        """May the student's .par differ from the exercise's in `key` ("SECTION.Key")?"""
        return key in self.keys or key.partition(".")[0] in self.sections


def read_exercise(path: Path | str) -> Exercise:
    """The exercise in `path`, checked; ExerciseError naming the file and line."""
    name = str(path)
    try:
        data = read_regular(path, MAX_BYTES)
    except FileNotFoundError:
        raise ExerciseError(name, "no such file") from None
    except OSError as exc:
        raise ExerciseError(name, f"cannot read: {exc.strerror or exc}") from None
    if len(data) > MAX_BYTES:
        raise ExerciseError(name, f"larger than {MAX_BYTES} bytes: not an exercise")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ExerciseError(name, "not UTF-8 text", data[: exc.start].count(b"\n") + 1) from None
    return parse_exercise(text, Path(path), hashlib.sha256(data).hexdigest())


def parse_exercise(text: str, path: Path, digest: str = "") -> Exercise:
    name = str(path)
    node, data = parse_yaml(text, name, lambda f, m, line: ExerciseError(f, m, line))
    lines = key_lines(node)
    base = path.parent

    def fail(reason: str, key: str = "") -> ExerciseError:
        line = lines.get(key)
        while line is None and "." in key:
            key = key.rsplit(".", 1)[0]
            line = lines.get(key)
        return ExerciseError(name, reason, line if line is not None else 1)

    if not isinstance(data, dict):
        raise fail(f"{NOT_A_MAPPING}: title, text, par, experiment, requirements, ...")
    unknown = [k for k in data if k not in TOP_KEYS]
    if unknown:
        raise fail(f"unknown key {unknown[0]!r} (one of {', '.join(TOP_KEYS)})", str(unknown[0]))
    for key in ("title", "text", "par", "experiment", "requirements"):
        if key not in data:
            raise fail(f"no {key!r}: an exercise needs title, text, par, experiment and requirements")
    title, body = _text(data, "title", fail), _text(data, "text", fail)
    par = _text(data, "par", fail).strip()
    par_path = base / par
    if par.lower().endswith(".par") or "/" in par:
        if not par_path.is_file():
            raise fail(f"par: no such file {par_path}", "par")
        par = str(par_path.resolve())
    runs_on = data.get("runs_on", "either")
    if runs_on not in RUNS_ON:
        raise fail(f"runs_on must be one of {', '.join(RUNS_ON)}, got {runs_on!r}", "runs_on")
    types, keys, sections = _may_change(data.get("may_change", {}), fail)
    experiment = _experiment(data["experiment"], base, fail)
    limit = data.get("time_limit")
    if limit is not None and (not is_finite_number(limit) or limit <= 0):
        raise fail(f"time_limit must be a positive number of seconds, got {limit!r}", "time_limit")
    identify = _identify(data.get("identify", {}), fail)
    reqs = data["requirements"]
    if not isinstance(reqs, list) or not reqs:
        raise fail("requirements is a list of requirements (- overshoot: {loop: 1, max: 10})", "requirements")
    requirements = tuple(_requirement(item, f"requirements.{i}", lines, fail) for i, item in enumerate(reqs))
    seen: dict[str, int] = {}
    for i, r in enumerate(requirements):
        if r.name in seen:
            raise fail(f"{r.name} is required twice", f"requirements.{i}")
        seen[r.name] = i
    reference = None
    if data.get("reference") is not None:
        ref = base / _text(data, "reference", fail).strip()
        if not ref.is_file():
            raise fail(f"reference: no such file {ref}", "reference")
        reference = ref.resolve()
    teacher = _text(data, "teacher", fail) if "teacher" in data else ""
    return Exercise(path.resolve(), digest, title, body, par, runs_on, types, keys, sections, experiment,
                    requirements, None if limit is None else float(limit), identify, reference, teacher)


def _number(value: Any) -> float | None:
    """A finite number as a float (YAML's int or float, not a bool), else None."""
    return float(value) if is_finite_number(value) else None


def _text(data: dict[str, Any], key: str, fail: Any) -> str:
    value = data[key]
    if not isinstance(value, str) or not value.strip():
        raise fail(f"{key} must be text, got {value!r}", key)
    return value


def _may_change(value: Any, fail: Any) -> tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]:
    if not isinstance(value, dict) or set(value) - {"types", "keys", "sections"}:
        raise fail("may_change is a mapping of types, keys and sections", "may_change")
    out: list[tuple[str, ...]] = []
    for part in ("types", "keys", "sections"):
        items = value.get(part, [])
        where = f"may_change.{part}"
        if not isinstance(items, list) or not all(isinstance(x, str) for x in items):
            raise fail(f"{where} is a list of names", where)
        for i, x in enumerate(items):
            if part == "types" and x not in TYPES:
                raise fail(f"{where}: unknown controller type {x!r} (one of {', '.join(TYPES)})", f"{where}.{i}")
            if part == "keys":
                try:
                    spec(x)
                except KeyError:
                    raise fail(f"{where}: unknown parameter {x!r}", f"{where}.{i}") from None
            if part == "sections" and x not in SECTIONS:
                raise fail(f"{where}: unknown section {x!r}", f"{where}.{i}")
        out.append(tuple(items))
    return out[0], out[1], out[2]


def _experiment(value: Any, base: Path, fail: Any) -> Experiment:
    where = "experiment"
    if not isinstance(value, dict) or set(value) - {"script", "own_run", "duration"}:
        raise fail("experiment is a mapping: script (or own_run) and duration", where)
    duration = _number(value.get("duration"))
    if duration is None or not 0 < duration <= MAX_DURATION:
        raise fail(f"experiment.duration must be seconds in (0, {MAX_DURATION:g}], got {value.get('duration')!r}",
                   "experiment.duration")
    if ("script" in value) == ("own_run" in value):
        raise fail("experiment needs one of script (the exercise's experiment) or own_run (the student's)", where)
    if "script" in value:
        script = value["script"]
        if not isinstance(script, str) or not (base / script).is_file():
            raise fail(f"experiment.script: no such file {base / str(script)}", "experiment.script")
        from quadtank_tui.files.script import ScriptError, read_script

        try:
            read_script(base / script)
        except ScriptError as exc:
            raise fail(f"experiment.script: {exc}", "experiment.script") from None
        return Experiment(duration, script=(base / script).resolve())
    own = value["own_run"]
    step = own.get("step") if isinstance(own, dict) else None
    if not isinstance(step, dict) or len(step) != 1 or set(own) - {"step", "mode"} or \
            own.get("mode", "Automatic") != "Automatic":
        raise fail("experiment.own_run needs {step: {\"REFERENCE ONE.Mean\": 0.1}, mode: Automatic}",
                   "experiment.own_run")
    ((key, given),) = step.items()
    delta = _number(given)
    if key not in ("REFERENCE ONE.Mean", "REFERENCE TWO.Mean") or delta is None or delta == 0:
        raise fail("experiment.own_run.step: a nonzero step of REFERENCE ONE.Mean or REFERENCE TWO.Mean",
                   "experiment.own_run.step")
    return Experiment(duration, own_run=OwnRun(str(key), delta))


def _identify(value: Any, fail: Any) -> Identify:
    if not isinstance(value, dict) or set(value) - {"method", "order", "zeros"}:
        raise fail("identify is a mapping: method, order, zeros", "identify")
    method = value.get("method", "oe")
    if method not in IDENTIFY_METHODS:
        raise fail(f"identify.method must be one of {', '.join(IDENTIFY_METHODS)}, got {method!r}",
                   "identify.method")
    order, zeros = value.get("order"), value.get("zeros", 0)
    for k, v, low in (("order", order, 1), ("zeros", zeros, 0)):
        if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < low or v > 10):
            raise fail(f"identify.{k} must be a whole number {low}..10, got {v!r}", f"identify.{k}")
    return Identify(str(method), order, int(zeros))


def _requirement(item: Any, where: str, lines: dict[str, int], fail: Any) -> Requirement:
    if not isinstance(item, dict) or len(item) != 1:
        raise fail("a requirement is one kind with its settings: - overshoot: {loop: 1, max: 10}", where)
    ((kind, opts),) = item.items()
    if kind not in WRITTEN:
        raise fail(f"unknown requirement {kind!r} (one of {', '.join(WRITTEN)})", where)
    k = KINDS[kind]
    if not isinstance(opts, dict):
        raise fail(f"{kind} needs a mapping, e.g. {{{'loop: 1, ' if k.what in ('step', 'design') else ''}"
                   f"{k.bound}: ...}}", where)
    line = lines.get(where, 0)
    allowed = {k.bound, "tolerance"} if k.what == "model" else {k.bound}
    if k.what in ("step", "design"):
        allowed.add("loop")
    if kind == "settling_time":
        allowed.add("band")
    if kind == "max_level":
        allowed.add("tank")
    if kind == "model_gain":
        allowed.add("element")
    extra = set(opts) - allowed
    if extra:
        raise fail(f"{kind}: unknown setting {sorted(map(str, extra))[0]!r} (it takes {', '.join(sorted(allowed))})",
                   f"{where}.{kind}")
    given = opts.get(k.bound, opts.get("tolerance"))
    limit = _number(given)
    if limit is None or (k.bound == "max" and limit < 0):
        raise fail(f"{kind} needs a number {k.bound}: ..., got {given!r}", f"{where}.{kind}")
    loop = opts.get("loop")
    if k.what in ("step", "design") and loop not in (1, 2):
        raise fail(f"{kind} needs loop: 1 or 2", f"{where}.{kind}")
    band = _number(opts.get("band", 0.02))
    if band is None or not 0 < band < 1:
        raise fail(f"{kind}.band is a share of the step in (0, 1), got {opts.get('band')!r}", f"{where}.{kind}.band")
    tank = opts.get("tank")
    if kind == "max_level" and tank not in (1, 2, 3, 4):
        raise fail("max_level needs tank: 1..4", f"{where}.{kind}")
    element = opts.get("element")
    if kind == "model_gain":
        element = str(element)
        if element not in ELEMENTS:
            raise fail(f"model_gain needs element: one of {', '.join(ELEMENTS)}", f"{where}.{kind}")
    return Requirement(str(kind), limit, loop, band, tank, element, line)
