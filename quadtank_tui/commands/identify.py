"""`quadtank identify LOG [LOG ...]`: models from experiment logs (step-response,
output-error, subspace or ARX), validated, next to the physical linearization.

Bad input (a missing column, too few rows, a constant input, no step) is one line
on stderr and exit status 2, through cli.main's handling of UsageError and ValueError.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING

from quadtank_tui.commands import UsageError, read_sampled, warn

if TYPE_CHECKING:
    from quadtank_tui.core.identify.crossval import Figure
    from quadtank_tui.core.identify.experiment import Identification
    from quadtank_tui.core.plants.johansson import PlantParams
    from quadtank_tui.files.figures.runs import Scale

METHODS = ("step", "oe", "n4sid", "arx", "physical")


#: The real-rig effects a physical fit can add (core.identify.physical.PHYSICS_NAMES).
PHYSICS_CHOICES = ("laminar", "overflow", "deadzone", "saturation")

def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "identify", help="identify the process from logs: step, output-error, subspace or ARX models",
        description="Fit models to experiment logs (each element from the log in which its input "
        "moves; n4sid from a log in which both move), validate them on the last part of each log, "
        "and compare the static gains, time constants, zeros and phase with the physical model "
        "linearized at the log's first row.",
    )
    p.add_argument("logs", nargs="+", metavar="LOG", help=".log files (SIMO: one per excited input)")
    p.add_argument("--method", choices=METHODS, default="oe",
                   help="step: Andersson's step-response structures; oe: output-error transfer functions "
                   "(default); n4sid: a MIMO state-space model (PO-MOESP); arx: least squares; physical: "
                   "the constants of the plant in use (--par) fitted by its own nonlinear simulator")
    p.add_argument("--inputs", nargs="+", metavar="U", help="inputs to use (default: those that move)")
    p.add_argument("--outputs", nargs="+", metavar="Y", help="outputs to use (default: y1 y2)")
    p.add_argument("--structure", type=int, choices=range(1, 6), default=1, metavar="1..5",
                   help="step structure: 1 K/(sT+1)^n, 2 K(sTz+1)/(sT+1)^n, 3 K/s, 4 K/(s(sT+1)), "
                   "5 K(sTz+1)/(s(sT+1)), all with e^-sL (default 1)")
    p.add_argument("--n", type=int, choices=range(1, 5), metavar="1..4",
                   help="n of step structures 1 and 2 (default: the best of 1..4)")
    p.add_argument("--order", type=int, metavar="N",
                   help="oe: poles per element (default 1 on the diagonal, 2 off it); "
                   "arx: na = nb (default 2); n4sid: states (default 4)")
    p.add_argument("--zeros", type=int, default=0, metavar="M", help="oe: zeros per element (default 0)")
    p.add_argument("--no-delay", action="store_true", help="oe: no dead time (L = 0)")
    p.add_argument("--start", nargs="+", metavar="NAME=VALUE",
                   help="manual starting values for step and oe fits: T=60 L=2 (oe: one T per "
                   "pole, T=30,90); K, Tz, y0 and the rest value are solved exactly and need none")
    p.add_argument("--validate", type=float, default=0.5, metavar="FRACTION",
                   help="share of each log kept for validation (default 0.5; 0 validates on "
                   "the identification data)")
    p.add_argument("--par", metavar="FILE",
                   help="the physical model to compare with: a .par file or a preset name "
                   "(default: the preset whose steady state matches the log's first row)")
    p.add_argument("--save", nargs="?", const="", metavar="PATH",
                   help="keep the model as JSON (default path: next to the first log, NAME.model.json); "
                   "physical: the fitted constants as a .par of the plant's kind (default NAME.par next to "
                   "the first log) with NAME.physical.json beside it")
    p.add_argument("--validate-on", nargs="+", metavar="LOG",
                   help="simulate the model on these logs' inputs and report fit %% and RMS (a linear "
                   "model from rest at the first row; physical: levels fitted to the first 20 rows)")
    p.add_argument("--free", nargs="+", metavar="NAME",
                   help="physical: the constants to fit (default: outlets, pumps and valves)")
    p.add_argument("--offsets", action="store_true",
                   help="physical: fit a sensor offset per output (the default: no rig's zero is exactly 0 V)")
    p.add_argument("--no-offsets", action="store_true", help="physical: no sensor offsets (the sensors read 0 V at 0)")
    p.add_argument("--physics", nargs="+", metavar="EFFECT", choices=("auto", "plain", *PHYSICS_CHOICES),
                   help="physical: the effects to fit besides Torricelli outlets: auto (default: the plain "
                   "model, extended when the logs ask), plain, or any of " + ", ".join(PHYSICS_CHOICES))
    p.add_argument("--budget", type=float, metavar="SECONDS",
                   help="physical: stop the fit after this much CPU time with its best point (default 90)")
    p.add_argument("--figure", metavar="FILE",
                   help="also draw the validation as a figure (.png, .svg or .pdf): per element the measured "
                   "and model output on the validation part, the residual autocorrelation and the coherence")
    p.add_argument("--figure-units", choices=("cm", "V", "norm"), default="cm",
                   help="the figure's levels in the plant's unit (cm, default: the sensors' gains of --par "
                   "or of the quadruple tank compared with), in V, or normalized as logged")
    p.add_argument("--json", action="store_true", help="print a JSON object instead of a report")
    p.set_defaults(handler=run)


def _physical(par: str | None, op: dict[str, float]) -> tuple[PlantParams | None, str, tuple[float, ...]]:
    """The physical model to compare with, its name, and the pump voltages to
    assume for an input the logs do not hold.  The comparison is with a quadruple
    tank's linearization: for another plant in use (a PLANT section) there is none
    (None), rather than the SIMULATION section's four tanks, which it is not."""
    from quadtank_tui.core.identify.compare import closest_setting
    from quadtank_tui.core.plants.johansson import SETTINGS

    if par is None:
        s = closest_setting(op)
        return s.params, f"{s.title} (the preset nearest the log's levels; --par to choose)", s.op.u
    if par in SETTINGS:
        s = SETTINGS[par]
        return s.params, s.title, s.op.u
    from quadtank_tui.files.par import read_par

    read = read_par(par)
    warn(read.warnings)
    if read.params.process is not None:  # another plant: no four-tank linearization to compare with
        return None, f"{par} ({read.params.process_plant().title})", (3.0, 3.0)
    return read.params.quadtank_constants(), par, (3.0, 3.0)


def _figure_units(units: str, par: str | None, params: PlantParams | None) -> dict[str, Scale]:
    """The figure's scales (files.figures.runs.scales) on the plant of `par`, or the
    quadruple tank compared with; normalized when there is neither."""
    from quadtank_tui.commands.identify_physical import starting_plant
    from quadtank_tui.core.plants import Plant, QuadTank
    from quadtank_tui.files.figures.runs import scales

    if par is not None:
        plant: Plant = starting_plant(par).plant
    elif params is not None:
        plant = QuadTank(params)
    else:
        return {}  # as logged
    return scales(units, plant)


def _sensor_gains(par: str | None, params: PlantParams | None) -> tuple[dict[str, float], str]:
    """Volts per level unit of each sensor of the plant in use (--par names it; else
    the quadruple tank compared with), and that unit."""
    from quadtank_tui.commands.identify_physical import starting_plant
    from quadtank_tui.core.identify.physical import sensor_gains
    from quadtank_tui.core.plants import Plant, QuadTank

    if par is not None:
        plant: Plant = starting_plant(par).plant
    elif params is not None:
        plant = QuadTank(params)
    else:  # _physical gives a quadruple tank whenever --par is absent
        raise ValueError("no plant to take the sensors' gains from: give --par")
    gains = sensor_gains(plant)
    return {f"y{i + 1}": float(g) for i, g in enumerate(gains)}, plant.states[0].unit


def cross_validate(ident: Identification, paths: list[str], gains: dict[str, float], unit: str) -> list[Figure]:
    """The identified model on each log's inputs: fit % and RMS of each output
    (volts: 10 V per log unit; levels through each sensor's gain in V per `unit`)."""
    from quadtank_tui.core.identify.crossval import figure, simulate_linear
    from quadtank_tui.core.plants.common import FULL_SCALE_V

    out = []
    for path in paths:
        log, tsamp = read_sampled(path)
        elements = {key: e.tf for key, e in ident.elements.items()}
        cols = log.columns()
        ym = simulate_linear(elements, ident.outputs, ident.inputs, cols, tsamp, path)
        out += [figure(path, o, cols[o], ym[o], FULL_SCALE_V, gains.get(o, float("nan")), unit)
                for o in ident.outputs]
    return out


def parse_start(items: list[str] | None) -> dict[str, object] | None:
    """`T=60 L=2` or `T=30,90` -> {"T": 60.0, "L": 2.0} / {"T": [30.0, 90.0]}."""
    if not items:
        return None
    out: dict[str, object] = {}
    for item in items:
        name, eq, value = item.partition("=")
        if not eq or name not in ("T", "L"):
            raise UsageError(f"--start takes T=VALUE and L=VALUE, got {item!r}")
        try:
            numbers = [float(x) for x in value.split(",")]
        except ValueError:
            raise UsageError(f"--start {name}: not a number in {value!r}") from None
        out[name] = numbers if name == "T" and "," in value else numbers[0]
    return out


def run(args: argparse.Namespace) -> int:
    if args.figure is not None:
        from quadtank_tui.files.figures import figure_format

        figure_format(args.figure)  # a name that cannot be written is refused before the fit
    from quadtank_tui.core.identify.compare import compare
    from quadtank_tui.core.identify.experiment import Options, Record, identify
    from quadtank_tui.core.identify.report import format_report, to_dict
    from quadtank_tui.files.model import from_identification, model_path, write_model

    if args.method == "physical":
        from quadtank_tui.commands import identify_physical

        if args.figure is not None:
            raise UsageError("--figure draws a linear model's validation; --method physical has none yet")
        return identify_physical.run(args)
    if args.free or args.offsets or args.no_offsets or args.physics or args.budget is not None:
        raise UsageError("--free, --offsets, --no-offsets, --physics and --budget belong to --method physical")
    if not 0.0 <= args.validate < 1.0:
        raise UsageError(f"--validate must be a fraction in [0, 1), got {args.validate:g}")
    if args.order is not None and args.order < 1:
        raise UsageError(f"--order must be >= 1, got {args.order}")
    records = []
    for path in args.logs:
        log, tsamp = read_sampled(path)
        records.append(Record(path, tsamp, log.columns()))
    opts = Options(method=args.method, inputs=tuple(args.inputs) if args.inputs else None,
                   outputs=tuple(args.outputs) if args.outputs else None, structure=args.structure,
                   n=args.n, order=args.order, zeros=args.zeros, delay=not args.no_delay,
                   fraction=1.0 - args.validate, start=parse_start(args.start))
    ident = identify(records, opts)
    from quadtank_tui.core.identify.feedback import closed_loop

    feedback = closed_loop([(r.name, r.columns) for r in records])
    params, name, v_default = _physical(args.par, ident.operating_point)
    cmp = None
    if params is None:
        warn([f"no physical comparison: {name} is not a quadruple tank"])
    elif all(k in ("u1", "u2") for k in ident.inputs) and all(k in ("y1", "y2") for k in ident.outputs):
        cmp = compare(ident.operating_point, params, ident.system.static_gains, ident.inputs,
                      ident.outputs, v_default)
    validation = cross_validate(ident, args.validate_on or [], *_sensor_gains(args.par, params))
    saved = None
    if args.save is not None:
        target = Path(args.save) if args.save else model_path(args.logs[0])
        saved = write_model(target, from_identification(ident))
    figure = None
    if args.figure is not None:
        from quadtank_tui.files.figures.identification import identification_figure
        from quadtank_tui.files.figures.style import save

        figure = save(identification_figure(ident, units=_figure_units(args.figure_units, args.par, params)),
                      args.figure)
    if args.json:
        out = to_dict(ident, cmp, name)
        out["closed_loop"] = feedback
        if saved is not None:
            out["model_file"] = str(saved)
        out["validation"] = [v.to_dict() for v in validation]
        if figure is not None:
            out["figure"] = str(figure)
        print(json.dumps(out, indent=2))
    else:
        print(format_report(ident, cmp, name))
        if feedback:
            print(feedback)
        if validation:
            print("Validation on other logs (the model from rest at each log's first row):")
            from quadtank_tui.commands.identify_physical import figure_line

            for v in validation:
                print(f"  {figure_line(v)}")
        if saved is not None:
            print(f"Model saved to {saved}")
        if figure is not None:
            print(f"Figure written to {figure}")
    return 0
