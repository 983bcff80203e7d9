"""`quadtank design`: PI/PID from a model (typed expression) with Andersson's
evaluation table, or both diagonal loops of the 2x2 process (`--par`: its physical
linearization; `--model-file`: an identified model) with the MIMO check and a step
through the real engine.

Heavy modules (numpy, scipy) are imported inside the handler: building the parser
must stay cheap for every other command.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from quadtank_tui.commands import warn

METHODS = ("lambda", "pi-ms", "pid-ms")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "design",
        help="design a PI/PID from a model (lambda, Ms-constrained) and evaluate it",
        description="Design a PI or PID controller from a model and print Kc, Ti, Td and "
        "Andersson's evaluation (Ms, margins, load-step IAE, Emax, u overshoot).  With --par, "
        "design both diagonal loops of the quadruple tank on its physical linearization and "
        "check the 2x2 loop.",
        epilog="Example: quadtank design --model '1.6592*exp(-2.4*s)/(1.07*s+1)^3' --method pi-ms --ms 1.4",
    )
    src = p.add_mutually_exclusive_group()
    src.add_argument("--model", metavar="EXPR",
                     help="transfer function in s with one exp(-L*s), e.g. '1.66*exp(-2.4*s)/(1.07*s+1)^3'; "
                     "one that starts with a minus needs '=': --model=-0.00651*exp(-2*s)/s")
    src.add_argument("--model-file", metavar="FILE",
                     help="a 2x2 model saved by `quadtank identify --save`: design both diagonal loops "
                     "on its G11 and G22 and check the 2x2 loop with its off-diagonal elements")
    p.add_argument("--par", metavar="FILE",
                   help="a .par file: design both diagonal loops on its physical linearization; with "
                   "--model-file, the base of --write-par and the simulator of the step")
    p.add_argument("--method", choices=METHODS, default=None,
                   help="lambda tuning, Ms-constrained PI or PID (default: pi-ms for --model, "
                   "lambda for --par)")
    p.add_argument("--lambda", dest="lam", type=float, metavar="L",
                   help="lambda, s (default: max(L, T) for --model, T/5 of each loop for --par)")
    p.add_argument("--ms", type=float, default=1.4, help="largest sensitivity Ms (default 1.4)")
    p.add_argument("--evaluate-on", metavar="EXPR",
                   help="evaluate on this model instead of the design model (e.g. a richer one)")
    p.add_argument("--no-step", action="store_true",
                   help="with --par: skip the step on the nonlinear simulator")
    p.add_argument("--write-par", metavar="OUT.par",
                   help="with --par: save the parameters with the designed controllers")
    p.add_argument("--figure", metavar="FILE",
                   help="also draw each designed loop as a figure (.png, .svg or .pdf): the reference step, "
                   "|S| and |T| with the Ms line, the Nyquist curve with the 1/Ms circle")
    p.add_argument("--json", action="store_true", help="print a JSON object instead of a table")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    if args.model is not None and args.par is not None:
        raise ValueError("--model and --par: choose one (--par designs both loops of the file's process)")
    if args.model is None and args.par is None and args.model_file is None:
        raise ValueError("a model is needed: --model EXPR, --model-file FILE or --par FILE")
    if args.figure is not None:
        from quadtank_tui.files.figures import figure_format

        figure_format(args.figure)  # a name that cannot be written is refused before the design
    if args.par is not None or args.model_file is not None:
        return _run_2x2(args)
    if args.write_par:
        raise ValueError("--write-par needs --par (a 2x2 design)")
    return _run_siso(args)


def _num(x: float) -> float | None:
    return None if not math.isfinite(x) else round(float(x), 6)


def _evaluation_json(ev: Any) -> dict[str, Any]:
    """An evaluation's figures for --json: floats rounded to 6 places, inf/nan null."""
    return {k: (_num(v) if isinstance(v, float) else v) for k, v in ev.to_dict().items()}


def _design_siso(g: Any, method: str, lam: float | None, ms: float) -> tuple[Any, str]:
    from quadtank_tui.core.design.lambda_tuning import first_order, lambda_for_tau, lambda_pi
    from quadtank_tui.core.design.optimize import pi_ms, pid_ms

    if method == "lambda":
        fo = first_order(g)
        if lam is None:
            lam = lambda_for_tau(fo, 1.0) if not fo.integrating else 3.0 * max(fo.L, 1.0)
        return lambda_pi(fo, lam), f"lambda = {lam:g} s on {fo}"
    if method == "pi-ms":
        return pi_ms(g, ms), f"PI, max ki subject to Ms <= {ms:g}"
    return pid_ms(g, ms), f"PID, max ki subject to Ms <= {ms:g} and Td <= Ti/4"


def _run_siso(args: argparse.Namespace) -> int:
    from quadtank_tui.core.design.evaluate import evaluate
    from quadtank_tui.core.design.expr import parse_model

    g = parse_model(args.model)
    target = parse_model(args.evaluate_on) if args.evaluate_on else g
    method = args.method or "pi-ms"
    c, how = _design_siso(g, method, args.lam, args.ms)
    ev = evaluate(c, target)
    figure = _figure(args.figure, [(method, target, c)], f"{how}; evaluated on {target}")
    if args.json:
        out = {"model": str(g), "method": method, "how": how, "Kc": c.Kc, "Ti": c.Ti, "Td": c.Td,
               "evaluated_on": str(target),
               "evaluation": _evaluation_json(ev)}
        if figure is not None:
            out["figure"] = str(figure)
        print(json.dumps(out, indent=2))
        return 0
    print(f"model      {g}")
    print(f"design     {how}")
    print(f"controller Kc = {c.Kc:.4g}   Ti = {c.Ti:.4g} s   Td = {c.Td:.4g} s"
          + ("   (derivative Td s/(1 + s Td/10) on y)" if c.Td > 0 else ""))
    print(f"evaluated on {target}" if args.evaluate_on else "evaluated on the design model")
    print(format_evaluation(ev))
    if figure is not None:
        print(f"figure     {figure}")
    return 0


def _figure(path: str | None, loops: list[tuple[str, Any, Any]], title: str) -> Path | None:
    """Draw the loops (name, model, PID) into `path`, if one was given."""
    if path is None:
        return None
    from quadtank_tui.files.figures.design import DesignedLoop, design_figure
    from quadtank_tui.files.figures.style import save

    return save(design_figure([DesignedLoop(*loop) for loop in loops], title), path)


def format_evaluation(ev: Any) -> str:
    """Andersson's row of figures, labelled."""
    if not ev.stable:
        return "closed loop UNSTABLE on this model"
    settle = "-" if ev.setpoint_settling is None else f"{ev.setpoint_settling:.3g} s"
    return "\n".join([
        f"Ms {ev.Ms:.3f}   phase margin {ev.phase_margin_deg:.1f} deg   gain margin {ev.gain_margin:.3g}"
        f"   delay margin {ev.delay_margin:.3g} s   crossover {ev.crossover:.3g} rad/s",
        f"load step {ev.load:.4g} at the process input:   IAE {ev.IAE:.4g}   Emax {ev.Emax:.3g}"
        f"   u overshoot {ev.u_overshoot:.3f}",
        f"setpoint step 1:   overshoot {ev.setpoint_overshoot_pct:.1f} %   settling (2 %) {settle}",
    ])


def identified_matrix(path: str | Path) -> Any:
    """G11 G12 / G21 G22 of a saved model, by the names y1 y2 and u1 u2 (V/V, which is
    also normalized/normalized: the design's units); every element must be there."""
    from quadtank_tui.files.model import ModelFileError, read_model

    m = read_model(path)
    rows = m.matrix_2x2()
    for o, row in enumerate(rows):
        for i, g in enumerate(row):
            if g is None:
                y, u = f"y{o + 1}", f"u{i + 1}"
                why = (f"{u} never moved in the logs" if y in m.outputs and u in m.inputs
                       else f"the model has {', '.join(m.inputs)} -> {', '.join(m.outputs)}")
                raise ModelFileError(str(path), f"no element {y}/{u} ({why}): the 2x2 design needs "
                                     "all four of u1, u2 -> y1, y2")
    return ((rows[0][0], rows[0][1]), (rows[1][0], rows[1][1]))


def _run_2x2(args: argparse.Namespace) -> int:
    from quadtank_tui.core.design.mimo import design_2x2, format_check, physical_model
    from quadtank_tui.core.design.apply import controller_values
    from quadtank_tui.engine.design_step import run_step
    from quadtank_tui.files.par import read_par, write_par

    if args.evaluate_on:
        raise ValueError("--evaluate-on is for --model; --par and --model-file check the 2x2 loop itself")
    if args.write_par and args.par is None:
        raise ValueError("--write-par with --model-file needs --par FILE for the other parameters")
    params = None
    if args.par is not None:
        read = read_par(args.par)
        warn(read.warnings)  # unknown keys or sections: said, as every command that reads a .par does
        params = read.params
    if args.model_file is not None:
        G = identified_matrix(args.model_file)
        source = f"{args.model_file}: identified model"
    else:
        assert params is not None
        G = physical_model(params.plant(), params.operating_levels())
        source = f"{args.par}: physical linearization at its operating levels"
    method = args.method or "lambda"
    chk = design_2x2(G, method, lam=(args.lam, args.lam), ms=args.ms)
    steps = []
    if not args.no_step and chk.stable and args.par is not None:
        duration = 600.0 if chk.lambda11_0 > 0 else 3000.0  # P+'s loop 2 is slow
        steps = [run_step(chk.pid_pair(), par=args.par, loop=i, duration=duration) for i in (1, 2)]
    written = None
    if args.write_par:
        out = Path(args.write_par)
        if out.suffix.lower() != ".par":
            raise ValueError(f"--write-par {out}: the file name must end in .par")
        assert params is not None
        written = write_par(out, params.with_values(controller_values(chk.pid_pair())))
    figure = _figure(args.figure, [(f"loop {d.loop} on {d.how}", d.model, d.controller) for d in chk.loops],
                     f"{source}, method {method}")
    if args.json:
        report = _check_json(chk, steps, written)
        if figure is not None:
            report["figure"] = str(figure)
        print(json.dumps(report, indent=2))
        return 0
    print(f"{source}, method {method}")
    print(format_check(chk))
    for s in steps:
        m = s.step
        settle = "not settled" if m.settling_time is None else f"{m.settling_time:.0f} s"
        print(f"nonlinear simulator, step 0.1 on r{s.loop}: overshoot {m.overshoot:.1f} %, "
              f"settling (2 %) {settle}, IAE {m.iae:.3f}, peak in y{3 - s.loop} {s.other_peak:.4f}")
    if written:
        print(f"wrote {written}")
    if figure is not None:
        print(f"figure written to {figure}")
    return 0


def _check_json(chk: Any, steps: list[Any], written: Path | None) -> dict[str, Any]:
    loops = []
    for d, lw in zip(chk.loops, chk.lambda11_wc):
        c = d.controller
        loops.append({"loop": d.loop, "designed_on": d.how, "model": str(d.model),
                      "Kc": c.Kc, "Ti": c.Ti, "Td": c.Td,
                      "evaluation": _evaluation_json(d.evaluation),
                      "lambda11_at_crossover_abs": abs(lw)})
    return {
        "det_G0": chk.det_G0, "lambda11_0": chk.lambda11_0, "stable": chk.stable,
        "slowest_pole": chk.slowest_pole, "loops": loops, "notes": list(chk.notes),
        "steps": [{"loop": s.loop, "overshoot_pct": s.step.overshoot,
                   "settling_time": s.step.settling_time, "IAE": s.step.iae,
                   "other_peak": s.other_peak} for s in steps],
        "written": None if written is None else str(written),
    }
