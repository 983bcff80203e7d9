"""`quadtank analyze`: a setting's or a `.par` file's linearization at its operating
levels: time constants, zeros, the RGA (the quadruple tank), or the generic report of
another plant."""

from __future__ import annotations

import argparse
import json
from typing import TYPE_CHECKING, Sequence

from quadtank_tui.commands import UsageError, warn
from quadtank_tui.core.plants.johansson import SETTINGS, steady_state_levels

if TYPE_CHECKING:
    from quadtank_tui.core.parameters import Parameters


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "analyze",
        help="linearize a setting: time constants, G(s), zeros, phase, RGA",
        description="Linearize the quadruple-tank process at an operating point and "
        "print its time constants, transfer matrix, transmission zeros, phase and RGA.",
    )
    source = p.add_mutually_exclusive_group()
    source.add_argument(
        "--preset", choices=sorted(SETTINGS), default="minphase",
        help="named physical setting (default: minphase, the paper's P-)",
    )
    source.add_argument(
        "--par", metavar="FILE",
        help="a .par file: its SIMULATION section gives the plant and operating levels",
    )
    p.add_argument(
        "--at", choices=("levels", "steady"), default="levels",
        help="linearize at the setting's operating levels (default) or at the steady "
        "state of its pump voltages",
    )
    p.add_argument("--json", action="store_true", help="print a JSON object instead of a table")
    p.set_defaults(handler=_cmd_analyze)


def _cmd_analyze(args: argparse.Namespace) -> int:
    from quadtank_tui.core.analysis import analyze, format_report

    h0: Sequence[float]
    if args.par is not None:
        from quadtank_tui.files.par import read_par

        if args.at == "steady":
            raise UsageError("--at steady needs pump voltages; a .par file gives operating levels only")
        read = read_par(args.par)
        warn(read.warnings)
        if read.params.process is not None:  # another rig (core.plants): its generic report
            return _analyze_other_plant(args, read.params)
        params, h0 = read.params.quadtank_constants(), read.params.operating_levels()
        source = {"par": args.par}
        title = f"{args.par}, linearized at its operating levels"
    else:
        setting = SETTINGS[args.preset]
        params, h0 = setting.params, setting.op.x
        where = "operating levels"
        if args.at == "steady":
            h0 = steady_state_levels(setting.op.u, params)
            where = f"steady state of v = ({setting.op.u[0]:.2f}, {setting.op.u[1]:.2f}) V"
        source = {"setting": setting.name}
        title = f"{setting.title}, linearized at the {where}"
    result = analyze(params, h0)
    if args.json:
        print(json.dumps({**source, "linearized_at": args.at, **result.to_dict()}, indent=2))
    else:
        print(format_report(title, result))
    return 0


def _analyze_other_plant(args: argparse.Namespace, params: Parameters) -> int:
    from quadtank_tui.core.plants.report import format_plant_report, report

    plant = params.process_plant()
    result = report(plant, params.process_levels())
    if args.json:
        print(json.dumps({"par": args.par, "linearized_at": args.at, **result.to_dict()}, indent=2))
    else:
        print(format_plant_report(f"{plant.title}, {args.par}, linearized at its operating levels", result))
    return 0
