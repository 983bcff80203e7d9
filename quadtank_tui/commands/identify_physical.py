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
from quadtank_tui.core.identify import IdentificationError
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
    from quadtank_tui.commands import read_sampled
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
    from quadtank_tui.core.identify.physical_auto import fit_auto

    start = starting_plant(args.par)
    plant = start.plant
    free = _free(args.free, plant)
    target = _save_path(args, start) if args.save is not None else None
    fitted_logs = experiments(args.logs, plant, args.outputs, args.inputs)
    if args.offsets and args.no_offsets:
        raise UsageError("--offsets and --no-offsets: one or the other")
    physics = args.physics or ["auto"]
    if ("auto" in physics or "plain" in physics) and len(physics) > 1:
        raise UsageError(f"--physics {' '.join(physics)}: auto and plain stand alone")
    budget = 90.0 if args.budget is None else args.budget
    if not 1.0 <= budget <= 3600.0:
        raise UsageError(f"--budget must be between 1 and 3600 s, got {budget:g}")
    offsets = not args.no_offsets
    with _Progress() as tick:
        if physics == ["auto"]:
            fit = fit_auto(plant, fitted_logs, free, offsets=offsets, progress=tick, budget_s=budget)
        else:
            fit = fit_physical(plant, fitted_logs, free, offsets=offsets, progress=tick, budget_s=budget,
                               physics=() if physics == ["plain"] else tuple(physics))
    loose = [n for n, _ in fit.undetermined if n in {e.name for e in fit.constants}]
    if fit.constants and len(loose) == len(fit.constants):
        raise IdentificationError(f"the logs do not determine {', '.join(loose)} (the outputs do not depend on "
                                  "them there): use logs in which the pumps move")
    offs = [o.value for o in fit.offsets] if not _plant_offsets(fit) else []
    validation: list[Figure] = []
    for exp in experiments(args.validate_on or [], plant, [f"y{o + 1}" for o in fitted_logs[0].outputs],
                           args.inputs):
        validation += validate_physical(fit.plant, exp, offs)[0]
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


def _plant_offsets(fit: PhysicalFit) -> bool:
    """Whether the fitted plant carries the sensor offsets itself (off1, off2, ...)."""
    known = fit.plant.values()
    return bool(fit.offsets) and all(f"off{e.name[1:].split('.')[0]}" in known for e in fit.offsets)


class _Progress:
    """The fit's progress on stderr when it is a terminal (simulations, RMS now, best
    so far), and Ctrl-C that stops the fit keeping its best point."""

    def __init__(self) -> None:
        import sys

        self.tty = sys.stderr.isatty()
        self.best = float("inf")
        self.stop = False
        self.old: Any = None

    def __enter__(self) -> _Progress:
        import signal
        import threading

        if threading.current_thread() is threading.main_thread():
            self.old = signal.signal(signal.SIGINT, self._interrupt)
        return self

    def _interrupt(self, signum: int, frame: Any) -> None:
        self.stop = True

    def __exit__(self, *exc: object) -> None:
        import signal
        import sys

        if self.old is not None:
            signal.signal(signal.SIGINT, self.old)
        if self.tty:
            sys.stderr.write("\r\033[K")
            sys.stderr.flush()

    def __call__(self, evaluations: int, rms: float) -> bool:
        import sys

        self.best = min(self.best, rms)
        if self.tty:
            sys.stderr.write(f"\r  fitting: {evaluations} simulations, RMS now {rms:.4g} V, best {self.best:.4g} V"
                             "  (Ctrl-C: stop and keep the best)\033[K")
            sys.stderr.flush()
        return not self.stop


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
    names = list(fit.names)
    return {
        "format": "quadtank-physical-fit", "version": 2, "method": "physical",
        "kind": fit.plant.kind, "par": start.name, "logs": [e.name for e in fit.experiments],
        "converged": fit.converged, "message": fit.message, "seconds": fit.seconds, "notes": list(fit.notes),
        "constants": {e.name: {"value": e.value, "stderr": e.stderr, "start": e.start} for e in fit.constants},
        "sensor_offsets_V": {e.name.split(".")[0]: {"value": e.value, "stderr": e.stderr} for e in fit.offsets},
        "correlation": {"names": names, "matrix": [[_num(v) for v in row] for row in fit.correlation]},
        "undetermined": [{"name": n, "determined_by": why} for n, why in fit.undetermined],
        "trade_offs": [{"a": a, "b": b, "correlation": c} for a, b, c in fit.tradeoffs],
        "moved_most": [{"name": n, "relative_change": v} for n, v in fit.moved],
        "starts": [{"start": s.label, "rms_V": _num(s.rms_start), "refined_rms_V": _num(s.rms_end)}
                   for s in fit.starts],
        "initial_levels": {e.name: list(x) for e, x in zip(fit.experiments, fit.initial)},
        "rms_V": fit.rms, "evaluations": fit.evaluations,
        "fit": [v.to_dict() for v in fit.fits()],
        "validation": [v.to_dict() for v in validation],
    }


def _num(v: float) -> float | None:
    """A number for JSON (NaN and inf have no JSON spelling: null)."""
    return float(v) if v == v and abs(v) != float("inf") else None


def format_report(fit: PhysicalFit, start: Start, validation: list[Figure]) -> str:
    p = fit.plant
    status = "converged" if fit.converged else f"NOT CONVERGED: {fit.message}"
    lines = [f"Physical fit of the {p.title} ({p.kind}) from {start.name}",
             f"  {len(fit.experiments)} log(s), {sum(e.rows for e in fit.experiments)} rows, "
             f"{fit.evaluations} simulations in {fit.seconds:.1f} s, RMS output error {fit.rms:.4g} V; {status}"]
    lines += [f"  {n}" for n in fit.notes]
    lines += ["", f"  {'constant':<10} {'.par value':>12} {'fitted':>14} {'+- (1 s.e.)':>12} {'change':>9}  unit"]
    in_par = start.plant.values()
    for e in fit.constants:
        was = in_par[e.name]  # a sensor range that was off (0) started at the highest reading
        change = f"{100 * (e.value / was - 1):+.2f} %" if was else ""
        lines.append(f"  {e.name:<10} {was:>12.6g} {e.value:>14.8g} {e.stderr:>12.3g} {change:>9}  "
                     f"{p.units.get(e.name, '')}")
    for e in fit.offsets:
        lines.append(f"  {e.name:<10} {0.0:>12.6g} {e.value:>14.6g} {e.stderr:>12.3g} {'':>9}  V")
    lines.append("")
    if not fit.converged and fit.moved:
        lines.append("  moved most from the .par: " + ", ".join(f"{n} {100 * v:+.1f} %" for n, v in fit.moved))
    for n, why in fit.undetermined:
        lines.append(f"  not determined by these logs: {n}; would be by {why}")
    for a, b, c in fit.tradeoffs:
        lines.append(f"  trade off: {a} and {b} (correlation {c:+.3f})")
    lines += _correlations(fit)
    tried = [s for s in fit.starts if s.rms_end == s.rms_end]
    if tried:
        lines.append("  starts refined: " + "; ".join(f"{s.label}: RMS {s.rms_start:.3g} -> {s.rms_end:.3g} V"
                                                     for s in tried)
                     + f" (of {len(fit.starts)} tried)")
    for exp, x in zip(fit.experiments, fit.initial):
        levels = ", ".join(f"{s.name} {v:.4g} {s.unit}" for s, v in zip(p.states, x))
        lines.append(f"  initial levels of {exp.name}: {levels}")
    lines.append("  fit on the logs fitted:")
    lines += [f"    {figure_line(v)}" for v in fit.fits()]
    if validation:
        lines.append("  validation (constants held; each log's initial levels, measured and unmeasured tanks, "
                     "estimated from its first 20 rows):")
        lines += [f"    {figure_line(v)}" for v in validation]
    return "\n".join(lines)


def _correlations(fit: PhysicalFit) -> list[str]:
    """The correlation matrix of the estimates (only when there are two or more)."""
    names = fit.names
    if len(names) < 2 or not fit.correlation:
        return []
    width = max(8, max(len(n) for n in names) + 1)
    out = ["  correlations of the estimates:", "    " + " " * width + "".join(f"{n:>{width}}" for n in names)]
    for n, row in zip(names, fit.correlation):
        out.append(f"    {n:<{width}}" + "".join(f"{v:>{width}.2f}" if v == v else f"{'n/a':>{width}}" for v in row))
    return out


def figure_line(v: Figure) -> str:
    """One output's figures: fit % (n/a for an output that does not move) and RMS."""
    fit = "n/a (the output does not move)" if v.fit_percent != v.fit_percent else f"{v.fit_percent:.2f} %"
    return (f"{v.log} {v.output}: fit {fit}, RMS {v.rms_log:.4g} (log units) = {v.rms_v:.4g} V "
            f"= {v.rms_level:.4g} {v.unit}")
