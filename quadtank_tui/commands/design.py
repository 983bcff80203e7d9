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
                     help="transfer function in s with one exp(-L*s), e.g. '1.66*exp(-2.4*s)/(1.07*s+1)^3' "
                     "or '-0.00651*exp(-2*s)/s'")
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
    p.add_argument("--sampling", type=float, metavar="SECONDS",
                   help="sampling time the loop runs at: design and evaluate the sampled loop (ZOH, "
                   "the PID as the program runs it); 0: continuous time (Andersson's tables).  Default: "
                   "the model file's sampling time, else --par's TSamp, else 0 for --model")
    p.add_argument("--u0", type=float, default=0.5, metavar="U",
                   help="--model with --sampling: the operating input (0..1 of the pump range) around "
                   "which the limited steps are simulated (default 0.5)")
    p.add_argument("--evaluate-on", metavar="EXPR",
                   help="evaluate on this model instead of the design model (e.g. a richer one)")
    p.add_argument("--no-step", action="store_true",
                   help="with --par: skip the preview (a step on each loop on the nonlinear simulator)")
    p.add_argument("--window", type=float, metavar="SECONDS",
                   help="length of each preview step, s (default: each step runs until it settles, at most "
                   "10 times the slowest time constant)")
    p.add_argument("--spread", type=int, default=100, metavar="N",
                   help="with --par: also run the pair on N plants drawn about the file's (+-10 %% outlets and "
                   "pumps, +-0.05 valve splits) and print the median and worst of each step (default 100; 0: off)")
    p.add_argument("--write-par", metavar="OUT.par",
                   help="with --par: save the parameters with the designed controllers (and TSamp "
                   "set to the sampling time they were designed for)")
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


def _check_sampling(h: float | None) -> None:
    if h is not None and not (math.isfinite(h) and h >= 0.0):
        raise ValueError(f"--sampling must be a time >= 0 s, got {h:g}")


def _design_siso(g: Any, method: str, lam: float | None, ms: float, h: float = 0.0) -> tuple[Any, str]:
    from quadtank_tui.core.design.lambda_tuning import first_order, lambda_for_tau, lambda_pi
    from quadtank_tui.core.design.optimize import pi_ms, pid_ms

    at = f", sampled at {h:g} s" if h > 0 else ""
    if method == "lambda":
        fo = first_order(g)
        if lam is None:
            lam = lambda_for_tau(fo, 1.0) if not fo.integrating else 3.0 * max(fo.L, 1.0)
        return lambda_pi(fo, lam, h), f"lambda = {lam:g} s on {fo}" + (f" (dead time + h/2{at})" if h else "")
    if method == "pi-ms":
        return pi_ms(g, ms, h=h), f"PI, max ki subject to Ms <= {ms:g}{at}"
    return pid_ms(g, ms, h=h), f"PID, max ki subject to Ms <= {ms:g} and Td <= Ti/4{at}"


def _run_siso(args: argparse.Namespace) -> int:
    from quadtank_tui.core.design.evaluate import evaluate
    from quadtank_tui.core.design.expr import parse_model

    _check_sampling(args.sampling)
    if not 0.0 <= args.u0 <= 1.0:
        raise ValueError(f"--u0 must be in 0..1 (a share of the pump range), got {args.u0:g}")
    g = parse_model(args.model)
    target = parse_model(args.evaluate_on) if args.evaluate_on else g
    method = args.method or "pi-ms"
    h = args.sampling or 0.0
    c, how = _design_siso(g, method, args.lam, args.ms, h)
    limits = None
    if h > 0.0:
        from quadtank_tui.core.design.sampled_eval import evaluate_sampled

        se = evaluate_sampled(c, target, h, u0=args.u0)
        ev, limits = se.evaluation, se.limits
    else:
        ev = evaluate(c, target)
    figure = _figure(args.figure, [(method, target, c, h, ev)], f"{how}; evaluated on {target}")
    if args.json:
        out = {"model": str(g), "method": method, "how": how, "Kc": c.Kc, "Ti": c.Ti, "Td": c.Td,
               "sampling_time": h, "evaluated_on": str(target),
               "evaluation": _evaluation_json(ev)}
        if limits is not None:
            out["limits"] = _limits_json(limits)
        if figure is not None:
            out["figure"] = str(figure)
        print(json.dumps(out, indent=2))
        return 0
    print(f"model      {g}")
    print(f"design     {how}")
    print(f"controller Kc = {c.Kc:.4g}   Ti = {c.Ti:.4g} s   Td = {c.Td:.4g} s"
          + ("   (derivative Td s/(1 + s Td/10) on y)" if c.Td > 0 else ""))
    print(f"evaluated on {target}" if args.evaluate_on else "evaluated on the design model")
    if h > 0.0:
        print(f"the loop sampled at h = {h:g} s (ZOH, the PID as the program runs it; "
              f"Nyquist frequency {math.pi / h:.3g} rad/s)")
    print(format_evaluation(ev))
    if limits is not None:
        print(format_limits(limits))
    if figure is not None:
        print(f"figure     {figure}")
    return 0


def _figure(path: str | None, loops: list[tuple[Any, ...]], title: str) -> Path | None:
    """Draw the loops (name, model, PID, sampling time, the evaluation printed) into
    `path`, if one was given: the figure's numbers are the text's."""
    if path is None:
        return None
    from quadtank_tui.files.figures.design import DesignedLoop, design_figure
    from quadtank_tui.files.figures.style import save

    return save(design_figure([DesignedLoop(*loop) for loop in loops], title), path)


def _limits_json(lc: Any) -> dict[str, Any]:
    def step(s: Any) -> dict[str, Any]:
        return {"overshoot_pct": _num(s.overshoot_pct), "settling_time": s.settling, "IAE": _num(s.iae),
                "time_at_pump_limit": s.at_limit, "input_reversals": _num(s.reversals)}
    return {"u0": lc.u0, "reference": step(lc.reference), "load": step(lc.load), "problem": lc.problem}


def format_limits(lc: Any) -> str:
    """The limited steps of the sampled loop and the verdict."""
    def one(name: str, s: Any) -> str:
        settle = "not settled" if s.settling is None else f"settling {s.settling:.3g} s"
        return (f"{name} step 0.1 with the pump in 0..1 around u0 = {lc.u0:g}: overshoot "
                f"{s.overshoot_pct:.1f} %, {settle}, at a pump limit {s.at_limit:.3g} s, "
                f"reversals {s.reversals:.0%}")
    return "\n".join([one("reference", lc.reference), one("load", lc.load),
                      f"verdict: {lc.problem or 'holds (no saturation beyond a fifth of settling, no chatter)'}"])


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
    from quadtank_tui.app.design import METHOD_DEFAULT, design_pair
    from quadtank_tui.core.design.apply import controller_values
    from quadtank_tui.core.design.mimo import format_check, model_in_use
    from quadtank_tui.files.par import read_par

    if args.evaluate_on:
        raise ValueError("--evaluate-on is for --model; --par and --model-file check the 2x2 loop itself")
    if args.write_par and args.par is None:
        raise ValueError("--write-par with --model-file needs --par FILE for the other parameters")
    _check_sampling(args.sampling)
    params = None
    if args.par is not None:
        read = read_par(args.par)
        warn(read.warnings)  # unknown keys or sections: said, as every command that reads a .par does
        params = read.params
    if params is not None and len(params.process_plant().inputs) == 1:
        return _run_one_pump(args, params)
    h_file = None
    if args.model_file is not None:
        from quadtank_tui.files.model import read_model

        G = identified_matrix(args.model_file)
        h_file = read_model(args.model_file).sampling_time
        source = f"{args.model_file}: identified model"
    else:
        assert params is not None
        from quadtank_tui.core.plants.base import SteadyStateError

        try:
            G = model_in_use(params)  # the plant in use (a PLANT section counts)
        except SteadyStateError as e:
            raise ValueError(f"{args.par}: PLANT.Level1/Level2: {e}; no linearization there (an "
                             "identified model, --model-file, brings its own operating point)") from None
        source = f"{args.par}: physical linearization at its operating levels"
    # the sampling time in force: asked for; else the identification experiment's (the
    # rate the lab runs the rig at, and --write-par sets TSamp to it); else the .par's
    if args.sampling is not None:
        h = args.sampling
    elif h_file:
        h = h_file
    else:
        h = params.tsamp if params is not None else 0.0
    method = args.method or METHOD_DEFAULT
    chk = design_pair(G, h, method=method, lam=(args.lam, args.lam), ms=args.ms)
    pv = rb = None
    if not (0 <= args.spread <= 2000):
        raise ValueError(f"--spread must be 0..2000 plants, got {args.spread}")
    if not args.no_step and chk.stable and params is not None:
        if h <= 0.0:
            raise ValueError("the preview on the simulator needs a sampling time: --sampling > 0")
        plan = _plan(params, chk.pid_pair(), G, h, args.window, _model_inputs(args.model_file))
        pv = plan.run()
        rb = _spread(args.spread, params, plan, pv)
    written = None
    if args.write_par:
        assert params is not None
        written = _write(args.write_par, params, controller_values(chk.pid_pair()), h)
    figure = _figure(args.figure, [(f"loop {d.loop} on {d.how}", d.model, d.controller, h, d.evaluation)
                                   for d in chk.loops],
                     f"{source}, method {method}")
    report = _check_json(chk, pv, written)
    report["robustness"] = None if rb is None else rb.to_dict()
    return _report(args.json, report, [f"{source}, method {method}", format_check(chk)], pv, written, figure, rb)


def _report(as_json: bool, report: dict[str, Any], lines: list[str], pv: Any, written: Path | None,
            figure: Path | None, rb: Any = None) -> int:
    """The design's JSON object, or its lines, the preview and what was written."""
    if as_json:
        if figure is not None:
            report["figure"] = str(figure)
        print(json.dumps(report, indent=2))
        return 0
    print("\n".join(lines))
    if pv is not None:
        from quadtank_tui.core.design.preview import format_preview

        print(format_preview(pv))
    if rb is not None:
        from quadtank_tui.core.design.robust import format_robustness

        print("robustness " + format_robustness(rb))
    if written:
        print(f"wrote {written}")
    if figure is not None:
        print(f"figure written to {figure}")
    return 0


def _write(path: str, params: Any, values: dict[str, Any], h: float) -> Path:
    """--write-par: the parameters with the designed controllers, TSamp at the
    sampling time they were designed for."""
    from quadtank_tui.files.par import write_par

    out = Path(path)
    if out.suffix.lower() != ".par":
        raise ValueError(f"--write-par {out}: the file name must end in .par")
    if h > 0.0:  # the controllers run at the sampling time they were designed for
        values["SAMPLING TIME.TSamp"] = h * 1000.0
    return write_par(out, params.with_values(values))


def _model_inputs(path: str | None) -> list[float] | None:
    """The pumps (0..1 of full scale) of a saved model's operating point, the rest
    its experiment started from; None without a model file or with an input missing."""
    if path is None:
        return None
    from quadtank_tui.files.model import read_model

    op = read_model(path).operating_point
    us = [op.get(f"u{i}") for i in (1, 2)]
    return [u for u in us if u is not None] or None


def _start(params: Any, inputs: list[float] | None) -> tuple[Any, Any] | None:
    """Levels and pump volts the preview starts from: the identification experiment's
    rest (a model is linear about it) when the model gives all the plant's inputs,
    else None (the parameters' operating point: app.design.operating_start)."""
    plant = params.process_plant()
    if inputs is not None and len(inputs) >= len(plant.inputs):
        volts = [u * s.full_scale for u, s in zip(inputs, plant.inputs)]
        return plant.steady_state(volts), volts
    return None


def _plan(params: Any, pair: Any, G: Any, h: float, window: float | None,
          inputs: list[float] | None = None, tr_keys: tuple[str, ...] | None = None) -> Any:
    """The designed controllers' preview on the nonlinear plant in use (app.design's
    plan, the one the Design screen runs)."""
    from quadtank_tui.app.design import TR_KEYS, preview_plan
    from quadtank_tui.core.design.preview import MAX_SAMPLES

    if window is not None and not (0 < window <= MAX_SAMPLES * h):  # NaN, inf, 1e12: 72.8 TiB asked for
        raise ValueError(f"--window must be a positive number of seconds up to {MAX_SAMPLES * h:g} "
                         f"({MAX_SAMPLES} samples of {h:g} s), got {window:g}")

    return preview_plan(params, pair, G, h, start=_start(params, inputs), window=window,
                        tr_keys=tr_keys or TR_KEYS)


def _spread(n: int, params: Any, plan: Any, pv: Any) -> Any:
    """The pair over n drawn plants (app.design.robustness_of), None when off."""
    if n == 0:
        return None
    from quadtank_tui.app.design import robustness_of

    try:
        return robustness_of(params, plan, pv, n=n)
    except ValueError as exc:
        warn([f"no spread: {exc}"])
        return None


def _run_one_pump(args: argparse.Namespace, params: Any) -> int:
    """A one-pump plant (the cascade): one loop, the controlled level from the pump,
    designed, previewed and written as element 12 of the matrix (core.design.apply)."""
    from quadtank_tui.core.design.apply import ONE_PUMP_ELEMENT, one_pump_values
    from quadtank_tui.core.design.evaluate import evaluate
    from quadtank_tui.core.design.mimo import design_loop, plant_loop

    plant = params.process_plant()
    (c,) = plant.controlled
    y = f"y{c + 1}"
    h_file = None
    if args.model_file is not None:
        from quadtank_tui.files.model import ModelFileError, read_model

        m = read_model(args.model_file)
        g = m.element(y, "u1")
        if g is None:
            raise ModelFileError(args.model_file, f"no element {y}/u1 (the model has {', '.join(m.inputs)} -> "
                                 f"{', '.join(m.outputs)}): {plant.title} controls {y} with its one pump u1")
        h_file = m.sampling_time
        source = f"{args.model_file}: identified model"
    else:
        g = plant_loop(plant, params.process_levels())
        source = f"{args.par}: physical linearization at its operating levels"
    h = args.sampling if args.sampling is not None else (h_file or params.tsamp)
    method = args.method or "lambda"
    ctrl = design_loop(g, method, lam=args.lam, ms=args.ms, h=h).rounded()
    ev = evaluate(ctrl, g, h=h)
    note = (f"{plant.title} has one pump: one loop is designed, {y} <- u1 (matrix element 12, "
            f"{ONE_PUMP_ELEMENT}, reference 2, in the full matrix)")
    pv = None
    if not args.no_step and ev.stable:
        if h <= 0.0:
            raise ValueError("the preview on the simulator needs a sampling time: --sampling > 0")
        pv = _plan(params, [ctrl], ((g,),), h, args.window, _model_inputs(args.model_file),
                   (f"{ONE_PUMP_ELEMENT}.Tr",)).run()
    written = _write(args.write_par, params, one_pump_values(ctrl), h) if args.write_par else None
    figure = _figure(args.figure, [(f"{y} <- u1", g, ctrl, h, ev)], f"{source}, method {method}")
    report = {"stable": ev.stable, "sampling_time": h, "notes": [note],
              "loops": [{"loop": 1, "output": y, "input": "u1", "element": ONE_PUMP_ELEMENT,
                         "designed_on": f"g{c + 1}1", "model": str(g), "Kc": ctrl.Kc, "Ti": ctrl.Ti,
                         "Td": ctrl.Td, "evaluation": _evaluation_json(ev)}],
              "preview": None if pv is None else pv.to_dict(),
              "written": None if written is None else str(written)}
    lines = [f"{source}, method {method}", note,
             f"loop {y} <- u1 on {g}: Kc = {ctrl.Kc:.4g}   Ti = {ctrl.Ti:.4g} s   Td = {ctrl.Td:.4g} s"
             + (f"   (sampled at h = {h:g} s)" if h > 0 else "   (continuous time)"), format_evaluation(ev)]
    return _report(args.json, report, lines, pv, written, figure)


def _check_json(chk: Any, pv: Any, written: Path | None) -> dict[str, Any]:
    loops = []
    for d, lw in zip(chk.loops, chk.lambda11_wc):
        c = d.controller
        loops.append({"loop": d.loop, "designed_on": d.how, "model": str(d.model),
                      "Kc": c.Kc, "Ti": c.Ti, "Td": c.Td,
                      "evaluation": _evaluation_json(d.evaluation),
                      "lambda11_at_crossover_abs": abs(lw)})
    return {
        "det_G0": chk.det_G0, "lambda11_0": chk.lambda11_0, "stable": chk.stable,
        "slowest_pole": chk.slowest_pole, "sampling_time": chk.sampling_time, "loops": loops,
        "notes": list(chk.notes),
        "preview": None if pv is None else pv.to_dict(),
        "written": None if written is None else str(written),
    }
