"""`quadtank icad`: Individual Channel Analysis of the 2x2 loop of a `.par` file.

The plant is the `.par` file's (its PLANT section, else the quadruple tank of its
SIMULATION section), linearized at its operating levels, from pump volts to sensor
volts.  The controllers are the file's diagonal elements (CONTROLLER ONE and FOUR,
converted from the loop's normalized units to volts per volt) unless --k1/--k2 give
transfer functions in s, in volts per volt (Murray-Smith's convention), e.g.
``--k1 "5*(1+6.2*s)/s"``.

The expressions are read by the design's model parser (core/design/expr.py, through
commands/icad_controllers.py), without a dead time.  Heavy modules load inside the
handler (tests/cli/test_cli_startup.py).
"""

from __future__ import annotations

import argparse
import json

from quadtank_tui.commands import warn
from quadtank_tui.core.plants.common import FULL_SCALE_V, PlantError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "icad", help="Individual Channel Analysis of a 2x2 loop (Murray-Smith)",
        description="Linearize the plant of a .par file at its operating levels and print the "
        "ICAD figures of its diagonal 2x2 loop: structure function gamma, channel crossovers, "
        "gain and phase margins, the distance of gamma h_j to (1, 0), closed-loop stability.",
    )
    p.add_argument("--par", metavar="FILE", required=True, help="a .par file (plant, levels, controllers)")
    p.add_argument("--k1", metavar="EXPR", help="controller of channel 1 in s, volts per volt "
                   "(default: the file's CONTROLLER ONE), e.g. '5*(1+6.2*s)/s'")
    p.add_argument("--k2", metavar="EXPR", help="controller of channel 2 (default: CONTROLLER FOUR)")
    p.add_argument("--json", action="store_true", help="print a JSON object instead of a table")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from quadtank_tui.commands.icad_controllers import coefficients, controller_from_par, controller_tf, show
    from quadtank_tui.core.icad import analyze_icad, format_icad
    from quadtank_tui.files.par import read_par

    read = read_par(args.par)
    warn(read.warnings)
    params = read.params
    plant = params.process_plant()
    if len(plant.inputs) != 2 or len(plant.controlled) != 2:
        raise PlantError(f"{args.par}: ICAD needs a 2x2 loop; the {plant.kind} plant has "
                         f"{len(plant.inputs)} pump(s) and {len(plant.controlled)} controlled level(s)")
    G = plant.control_model(params.process_levels())
    family = params.control.family.value
    ks = []
    for i, (expr, element) in enumerate(((args.k1, params.controllers[0]), (args.k2, params.controllers[3]))):
        scale = plant.inputs[i].full_scale / FULL_SCALE_V
        ks.append(controller_tf(expr, f"--k{i + 1}") if expr else controller_from_par(element, family, scale))
    result = analyze_icad(G, ks[0], ks[1])
    levels = ", ".join(f"{s.name} = {x:g} {s.unit}" for s, x in zip(plant.states, params.process_levels()))
    if args.json:
        print(json.dumps({"par": args.par, "plant": plant.kind, "levels": list(params.process_levels()),
                          "k1": coefficients(ks[0]), "k2": coefficients(ks[1]), **result.to_dict()}, indent=2))
    else:
        print(format_icad(f"{plant.title}, {args.par}, linearized at {levels}\n"
                          f"k1 = {show(ks[0])}    k2 = {show(ks[1])}   (volts per volt)", result))
    return 0
