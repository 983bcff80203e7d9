"""Identified models as small JSON files, kept next to the log they came from
(`logs/NAME.model.json`), so that design (`--model-file`) can read them later.

    {
      "format": "quadtank-model", "version": 1,
      "method": "oe",                       # step | oe | n4sid | arx
      "logs": ["logs/pminus-u1.log", "logs/pminus-u2.log"],
      "sampling_time": 1.0,                 # s
      "inputs": ["u1", "u2"], "outputs": ["y1", "y2"],
      "operating_point": {"u1": 0.3, "u2": 0.3, "y1": 0.613, "y2": 0.639},
      "fit_percent": {"y1": 99.2, "y2": 99.0},
      "elements": [[{"num": [2.58], "den": [62.1, 1.0], "delay": 0.0}, ...], ...],
      "static_gains": [[2.58, 1.49], [1.41, 2.85]],
      "zeros": [[-0.0594, 0.0], [-0.0174, 0.0]], "phase": "minimum"
    }

`elements[o][i]` is G from input i to output o: DelayTF coefficients in descending
powers of s (time in s, gains in V/V), null when that input never moved.  The
operating point is in the log's normalized units (a fraction of 10 V); the model
works in deviations from it.  static_gains, zeros and phase are written for a reader
without this program; read_model recomputes nothing from them.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from quadtank_tui.core.delaytf import DelayTF, ModelError
from quadtank_tui.core.ranges import is_finite_number
from quadtank_tui.files.atomic import atomic_write_text
from quadtank_tui.files.regular import read_regular

if TYPE_CHECKING:
    from quadtank_tui.core.identify.experiment import Identification

FORMAT = "quadtank-model"
VERSION = 1
#: A model file is a few kilobytes; anything far larger is not one.
MAX_BYTES = 1_000_000
#: The highest degree of an element's numerator or denominator: identification
#: fits up to a few poles, and design's work grows with the order (a denominator
#: of 5,000 coefficients took 77 s and 504 MB before it was refused).
MAX_DEGREE = 20
SUFFIX = ".model.json"


class ModelFileError(ValueError):
    """A model file refused; the message names the file and the field."""

    def __init__(self, file: str, reason: str) -> None:
        super().__init__(f"{file}: {reason}")
        self.file, self.reason = file, reason


@dataclass(frozen=True)
class ModelFile:
    """What a model file holds (see the module's docstring)."""

    elements: tuple[tuple[DelayTF | None, ...], ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    method: str
    logs: tuple[str, ...] = ()
    sampling_time: float | None = None
    operating_point: dict[str, float] = field(default_factory=dict)
    fit_percent: dict[str, float] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)

    def element(self, output: str, input: str) -> DelayTF | None:
        """G from `input` to `output` by name (KeyError for a name not in the model)."""
        return self.elements[self.outputs.index(output)][self.inputs.index(input)]

    def matrix_2x2(self) -> list[list[DelayTF | None]]:
        """[[G11, G12], [G21, G22]] by the names y1 y2 and u1 u2 (what the design's
        loops use); None for an element that is not in the model."""
        return [[self.element(y, u) if y in self.outputs and u in self.inputs else None
                 for u in ("u1", "u2")] for y in ("y1", "y2")]


def model_path(log: Path | str) -> Path:
    """`logs/NAME.model.json` for `logs/NAME.log`."""
    p = Path(log)
    return p.with_name(p.name.removesuffix(".log") + SUFFIX)


def from_identification(ident: Identification) -> ModelFile:
    """What `quadtank identify --save` and the Identify screen's Keep write."""
    from quadtank_tui.core.identify.report import to_dict

    data = to_dict(ident, None, "")
    return ModelFile(
        elements=ident.system.elements, inputs=ident.inputs, outputs=ident.outputs, method=ident.method,
        logs=ident.records, sampling_time=ident.h, operating_point=ident.operating_point,
        fit_percent=ident.fit_percent, extra={k: data[k] for k in ("static_gains", "zeros", "phase")})


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def write_model(path: Path | str, model: ModelFile) -> Path:
    """Write atomically (a reader never sees half a file)."""
    data: dict[str, Any] = {
        "format": FORMAT,
        "version": VERSION,
        "method": model.method,
        "logs": list(model.logs),
        "sampling_time": model.sampling_time,
        "inputs": list(model.inputs),
        "outputs": list(model.outputs),
        "operating_point": model.operating_point,
        "fit_percent": {k: _finite(v) for k, v in model.fit_percent.items()},
        "elements": [[None if g is None else {"num": list(g.num), "den": list(g.den), "delay": g.delay}
                      for g in row] for row in model.elements],
        **model.extra,
    }
    return atomic_write_text(path, json.dumps(data, indent=2) + "\n")


def read_model(path: Path | str) -> ModelFile:
    """Read and check a model file; every problem is one ModelFileError line."""
    name = str(path)
    try:
        data = read_regular(path, MAX_BYTES)  # a FIFO or a device is refused, never read
    except FileNotFoundError:
        raise ModelFileError(name, "no such file") from None
    except OSError as exc:
        raise ModelFileError(name, f"cannot read: {exc.strerror or exc}") from None
    if len(data) > MAX_BYTES:
        raise ModelFileError(name, f"larger than {MAX_BYTES} bytes: not a model file")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ModelFileError(name, "not UTF-8 text: not a model file") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ModelFileError(name, f"not JSON (line {exc.lineno}: {exc.msg})") from None
    except RecursionError:  # 100,000 nested [ : the parser's stack, before any field is looked at
        raise ModelFileError(name, "nested deeper than any model file (lists or objects inside each other): "
                             "not a model file") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ModelFileError(name, f"not a model file (no \"format\": \"{FORMAT}\")")
    if data.get("version") != VERSION:
        raise ModelFileError(name, f"version {data.get('version')!r} is not supported (this program reads {VERSION})")
    inputs = _names(name, data, "inputs")
    outputs = _names(name, data, "outputs")
    rows = data.get("elements")
    if not isinstance(rows, list) or len(rows) != len(outputs) or not all(
            isinstance(r, list) and len(r) == len(inputs) for r in rows):
        raise ModelFileError(name, f"elements must be {len(outputs)} rows of {len(inputs)} (outputs x inputs)")
    elements = tuple(tuple(_element(name, f"elements[{o}][{i}]", g) for i, g in enumerate(row))
                     for o, row in enumerate(rows))
    ts = data.get("sampling_time")
    if ts is not None and (not is_finite_number(ts) or not ts > 0):
        raise ModelFileError(name, f"sampling_time must be a positive number of seconds, got {ts!r}")
    known = {"format", "version", "method", "logs", "sampling_time", "inputs", "outputs",
             "operating_point", "fit_percent", "elements"}
    return ModelFile(
        elements, inputs, outputs, str(data.get("method", "")),
        tuple(str(x) for x in data.get("logs", []) or []), ts,
        _numbers(name, data, "operating_point"), _numbers(name, data, "fit_percent"),
        {k: v for k, v in data.items() if k not in known},
    )


def _names(file: str, data: dict[str, Any], key: str) -> tuple[str, ...]:
    v = data.get(key)
    if not isinstance(v, list) or not v or not all(isinstance(x, str) for x in v) or len(set(v)) != len(v):
        raise ModelFileError(file, f"{key} must be a non-empty list of distinct names")
    return tuple(v)


def _numbers(file: str, data: dict[str, Any], key: str) -> dict[str, float]:
    v = data.get(key) or {}
    if not isinstance(v, dict):
        raise ModelFileError(file, f"{key} must be a mapping of name to number")
    out = {}
    for k, x in v.items():
        if x is None:
            continue
        if not is_finite_number(x):
            raise ModelFileError(file, f"{key}.{k} must be a finite number, got {str(x)[:40]}")
        out[str(k)] = float(x)
    return out


def _element(file: str, where: str, g: Any) -> DelayTF | None:
    if g is None:
        return None
    if not isinstance(g, dict):
        raise ModelFileError(file, f"{where} must be null or {{num, den, delay}}")
    try:
        num, den = _coeffs(g.get("num")), _coeffs(g.get("den"))
        delay = g.get("delay", 0.0)
        if not is_finite_number(delay):
            raise ValueError(f"delay must be a finite number of seconds, got {str(delay)[:40]}")
        return DelayTF(num, den, float(delay))
    except (ModelError, TypeError, ValueError) as exc:
        raise ModelFileError(file, f"{where}: {exc}") from None


def _coeffs(v: Any) -> tuple[float, ...]:
    if not isinstance(v, list) or not v or not all(is_finite_number(x) for x in v):
        raise ValueError("num and den must be non-empty lists of finite numbers")
    if len(v) > MAX_DEGREE + 1:
        raise ValueError(f"a polynomial of degree {len(v) - 1}: at most {MAX_DEGREE} in a model file "
                         f"({MAX_DEGREE + 1} coefficients)")
    return tuple(float(x) for x in v)
