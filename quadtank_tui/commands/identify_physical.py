"""`quadtank identify LOG --method physical`: the constants of the plant in use
fitted to logs by its own nonlinear simulator (core.identify.physical), validated
on other logs, saved as a `.par` of the same plant kind.

`--par` names the plant kind and the starting values (a `.par` file or a preset;
default: the built-in quadruple tank at P-).  `--save` writes NAME.par next to the
first log (NAME: the log's name), with NAME.physical.json beside it; the `.par` in
use is never written.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from quadtank_tui.commands import UsageError, warn
from quadtank_tui.core.identify.crossval import Figure
from quadtank_tui.core.identify.physical import Experiment, PhysicalFit
from quadtank_tui.core.plants import Plant


@dataclass(frozen=True)
class Start:
    """The plant the fit starts from, and the `.par` text it came from."""

    plant: Plant
    name: str
    text: str
    path: Path | None


def starting_plant(par: str | None) -> Start:
    """The plant in use of `--par` (a file, or a preset name) and its file's text."""
    from quadtank_tui.core.parameters import NAMED_SETTINGS, PRESET
    from quadtank_tui.files.par import format_par, parse_par

    if par is None or (par in NAMED_SETTINGS and not Path(par).is_file()):
        params = PRESET if par is None else NAMED_SETTINGS[par]
        from datetime import datetime

        text = format_par(params, datetime(2026, 1, 1))
        return Start(params.process_plant(), par or "the built-in values (P-)", text, None)
    path = Path(par)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UsageError(f"{par}: no such .par file or preset") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"{par}: cannot read: {exc}") from None
    read = parse_par(text, name=par)
    warn(read.warnings)
    return Start(read.params.process_plant(), par, text, path)


def experiments(paths: list[str], plant: Plant, outputs: list[str] | None,
                inputs: list[str] | None) -> list[Experiment]:
    """Each log as an experiment of `plant` (every pump of it must be logged)."""
    from quadtank_tui.commands.identify import read_sampled
    from quadtank_tui.core.identify.physical import experiment_from_columns

    pumps = [f"u{i + 1}" for i in range(len(plant.inputs))]
    for u in inputs or ():
        if u not in pumps:
            raise UsageError(f"--inputs {u}: a {plant.kind} has the pumps {' '.join(pumps)}")
    out = []
    for path in paths:
        log, tsamp = read_sampled(path)
        out.append(experiment_from_columns(path, tsamp, log.columns(), plant, outputs))
    return out


def run(args: argparse.Namespace) -> int:
    from quadtank_tui.core.identify.physical import fit_physical, validate_physical

    start = starting_plant(args.par)
    plant = start.plant
    free = _free(args.free, plant)
    target = _save_path(args, start) if args.save is not None else None
    fitted_logs = experiments(args.logs, plant, args.outputs, args.inputs)
    fit = fit_physical(plant, fitted_logs, free, offsets=args.offsets)
    offsets = [o.value for o in fit.offsets]
    validation: list[Figure] = []
    for exp in experiments(args.validate_on or [], plant, [f"y{o + 1}" for o in fitted_logs[0].outputs],
                           args.inputs):
        validation += validate_physical(fit.plant, exp, offsets)[0]
    saved = _save(target, args.logs, start, fit) if target is not None else []
    if args.json:
        out = to_dict(fit, start, validation)
        out["saved"] = [str(p) for p in saved]
        print(json.dumps(out, indent=2))
    else:
        print(format_report(fit, start, validation))
        for p in saved:
            print(f"saved {p}")
    return 0


def _free(names: list[str] | None, plant: Plant) -> tuple[str, ...] | None:
    if not names:
        return None
    known = plant.values()
    for n in names:
        if n not in known:
            raise UsageError(f"--free {n}: a {plant.kind} has no constant {n} (it has {', '.join(known)})")
    return tuple(names)


def _save_path(args: argparse.Namespace, start: Start) -> Path:
    """Where --save writes the .par: NAME.par next to the first log, or PATH."""
    first = Path(args.logs[0])
    target = Path(args.save) if args.save else first.with_name(first.name.removesuffix(".log") + ".par")
    if target.suffix != ".par":
        raise UsageError(f"--save {target}: the fitted constants are written to a .par file")
    if start.path is not None and target.resolve() == start.path.resolve():
        raise UsageError(f"--save {target}: that is the .par in use; name another file")
    return target


def _save(target: Path, logs: list[str], start: Start, fit: PhysicalFit) -> list[Path]:
    """The fitted constants in a copy of the starting file at `target`, and
    NAME.physical.json beside it."""
    from quadtank_tui.files.atomic import atomic_write_text
    from quadtank_tui.files.physical_par import with_fit

    notes = {e.name: f"+- {e.stderr:.3g} (1 standard error); was {e.start:.8g}" for e in fit.constants}
    header = [f"Constants fitted by `quadtank identify --method physical` to {', '.join(logs)}",
              f"starting from {start.name}; RMS output error {fit.rms:.4g} V"]
    text = with_fit(start.text, str(target), fit.plant, notes, header)
    atomic_write_text(target, text, encoding="utf-8")
    js = target.with_name(target.name.removesuffix(".par") + ".physical.json")
    atomic_write_text(js, json.dumps(to_dict(fit, start, []), indent=2) + "\n", encoding="utf-8")
    return [target, js]


def to_dict(fit: PhysicalFit, start: Start, validation: list[Figure]) -> dict[str, Any]:
    return {
        "format": "quadtank-physical-fit", "version": 1, "method": "physical",
        "kind": fit.plant.kind, "par": start.name, "logs": [e.name for e in fit.experiments],
        "constants": {e.name: {"value": e.value, "stderr": e.stderr, "start": e.start} for e in fit.constants},
        "sensor_offsets_V": {e.name.split(".")[0]: {"value": e.value, "stderr": e.stderr} for e in fit.offsets},
        "initial_levels": {e.name: list(x) for e, x in zip(fit.experiments, fit.initial)},
        "rms_V": fit.rms, "evaluations": fit.evaluations,
        "fit": [v.to_dict() for v in fit.fits()],
        "validation": [v.to_dict() for v in validation],
    }


def format_report(fit: PhysicalFit, start: Start, validation: list[Figure]) -> str:
    p = fit.plant
    lines = [f"Physical fit of the {p.title} ({p.kind}) from {start.name}",
             f"  {len(fit.experiments)} log(s), {sum(e.rows for e in fit.experiments)} rows, "
             f"{fit.evaluations} simulations, RMS output error {fit.rms:.4g} V", "",
             f"  {'constant':<10} {'.par value':>12} {'fitted':>14} {'+- (1 s.e.)':>12} {'change':>9}  unit"]
    in_par = start.plant.values()
    for e in fit.constants:
        was = in_par[e.name]  # a sensor range that was off (0) started at the highest reading
        change = f"{100 * (e.value / was - 1):+.2f} %" if was else ""
        lines.append(f"  {e.name:<10} {was:>12.6g} {e.value:>14.8g} {e.stderr:>12.3g} {change:>9}  "
                     f"{p.units.get(e.name, '')}")
    for e in fit.offsets:
        lines.append(f"  {e.name:<10} {0.0:>12.6g} {e.value:>14.6g} {e.stderr:>12.3g} {'':>9}  V")
    lines.append("")
    for exp, x in zip(fit.experiments, fit.initial):
        levels = ", ".join(f"{s.name} {v:.4g} {s.unit}" for s, v in zip(p.states, x))
        lines.append(f"  initial levels of {exp.name}: {levels}")
    lines.append("  fit on the logs fitted:")
    lines += [f"    {figure_line(v)}" for v in fit.fits()]
    if validation:
        lines.append("  validation (constants held; initial levels fitted to the first 20 rows):")
        lines += [f"    {figure_line(v)}" for v in validation]
    return "\n".join(lines)


def figure_line(v: Figure) -> str:
    """One output's figures: fit % (n/a for an output that does not move) and RMS."""
    fit = "n/a (constant)" if v.fit_percent != v.fit_percent else f"{v.fit_percent:.2f} %"
    return (f"{v.log} {v.output}: fit {fit}, RMS {v.rms_log:.4g} (log units) = {v.rms_v:.4g} V "
            f"= {v.rms_level:.4g} {v.unit}")
