"""`quadtank mpc`: the MPC design a `.par` file's plant gets, and how it compares
with the file's PI controllers on the nonlinear simulator.

The design: operating point, weights, horizons, constraints, the unconstrained gain
(the LQR the MPC equals without active limits) and its closed-loop poles.  Then the
nonlinear plant (core.controllers.mpc.simulate) runs a step on each loop (announced: the MPC
previews it) and a leak in tank 1 under the MPC and under the PI matrix: IAE per
loop, overshoot, time at a pump limit, level-limit violations, failed solves and
solve time p50 / p99.  Bad input is one line and exit status 2 (cli.main).
The numeric stack loads inside the handler, so other commands do not pay for it.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

from quadtank_tui.commands import UsageError, params_of


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "mpc",
        help="MPC design of a .par file's plant and its comparison with the file's PI on the simulator",
        description="Design the model predictive controller (linear, constrained, offset-free, "
        "Kalman filter, OSQP) on the plant a .par file describes, print it, then compare it with "
        "the file's PI controllers on the nonlinear simulator: a reference step on each loop, then "
        "a leak in tank 1.",
    )
    p.add_argument("--par", metavar="FILE", help="a .par file (default: the built-in preset, the paper's P-)")
    p.add_argument("--horizon", metavar="N", type=int,
                   help="prediction horizon, prediction steps (default: the file's MPC.Horizon)")
    p.add_argument("--step", metavar="SECONDS", type=float,
                   help="prediction step, s, rounded to whole sampling times; 0: the sampling time "
                   "(default: the file's MPC.Step)")
    p.add_argument("--sampling", metavar="SECONDS", type=float,
                   help="sampling time, s (overrides SAMPLING TIME.TSamp; a longer one simulates faster)")
    p.add_argument("--phase", metavar="SECONDS", type=float, default=300.0,
                   help="seconds between the steps and the leak (default 300)")
    p.add_argument("--no-compare", action="store_true", help="print the design only")
    p.add_argument("--json", action="store_true", help="print a JSON object (keys design, comparison)")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from quadtank_tui.core.controllers.mpc.predictive import design_mpc
    from quadtank_tui.core.controllers.mpc.model import plant_in_use
    from quadtank_tui.core.parameters import TSAMP, TSAMP_MAX_MS, TSAMP_MIN_MS
    from quadtank_tui.core.ranges import ParameterError

    params, source = params_of(args.par)
    if args.sampling is not None:
        try:
            params = params.with_values({TSAMP: args.sampling * 1000.0})
        except ParameterError:
            raise UsageError(f"--sampling: {args.sampling:g} s is outside "
                             f"{TSAMP_MIN_MS / 1000:g}..{TSAMP_MAX_MS / 1000:g} s") from None
    if not (math.isfinite(args.phase) and 10.0 <= args.phase <= 1e5):
        raise UsageError(f"--phase: {args.phase:g} s is outside 10..100000 s")
    base = mpc_settings(params)
    settings = base
    for option, key, value in (("--horizon", "horizon", args.horizon), ("--step", "step", args.step)):
        try:
            settings = settings if value is None else _replace(settings, **{key: value})
        except ParameterError as exc:
            raise UsageError(f"{option}: {exc.reason}") from None
    plant, levels = plant_in_use(params)
    try:
        d = design_mpc(plant, levels, settings, params.tsamp)
    except ParameterError as exc:
        raise UsageError(f"{source}: {exc}") from None
    out: dict[str, Any] = {"source": source, "design": design_dict(d, plant)}
    if not args.no_compare:
        if not args.json:
            print(format_design(source, out["design"]), flush=True)
            print(f"simulating {1 + len(plant.controlled)} phases of {args.phase:g} s at T = {params.tsamp:g} s ...",
                  file=sys.stderr, flush=True)
        out["comparison"] = compare(params, plant, d, args.phase)
        print(json.dumps(out, indent=2) if args.json else format_comparison(out["comparison"]))
        return 0
    print(json.dumps(out, indent=2) if args.json else format_design(source, out["design"]))
    return 0


def mpc_settings(params: Any) -> Any:
    """The MPC settings of the parameters (the file's MPC section, else the defaults)."""
    return params.mpc


def _replace(s: Any, **changes: Any) -> Any:
    from dataclasses import replace

    return replace(s, **changes)


def _pairs(values: Any) -> list[list[float]]:
    return [[complex(v).real, complex(v).imag] for v in values]


def design_dict(d: Any, plant: Any) -> dict[str, Any]:
    """The design as plain JSON values (plant units: levels in the plant's unit, V)."""
    import numpy as np

    mdl, s, w = d.model, d.settings, d.weights
    poles_z = d.closed_loop_poles()
    rate = bool(np.any(w.S))
    K = w.K if rate else w.K[:, : mdl.n]
    with np.errstate(divide="ignore"):
        poles_s = [complex(np.log(complex(z))) / d.prediction.T if z != 0 else complex(-math.inf) for z in poles_z]
    return {
        "plant": plant.kind,
        "unit": plant.states[0].unit,
        "sampling_time": mdl.T,
        "prediction_step": d.prediction.T,
        "x_e": mdl.x_e.tolist(),
        "u_e": mdl.u_e.tolist(),
        "note": mdl.note,
        "horizon": s.horizon,
        "control_horizon": s.moves,
        "output_weight": s.output_weight,
        "input_weight": s.input_weight,
        "rate_weight": s.rate_weight,
        "Q_diag": np.diag(w.Q).tolist(),
        "R_diag": np.diag(w.R).tolist(),
        "S_diag": np.diag(w.S).tolist(),
        "slack_weight": s.slack_weight,
        "preview": s.preview,
        "disturbance": s.disturbance,
        "measured": [i + 1 for i in mdl.measured],
        "tracked": [i + 1 for i in mdl.tracked],
        "u_min": mdl.u_lo.tolist(),
        "u_max": mdl.u_hi.tolist(),
        "rate_limit": s.rate_limit,
        "level_min": mdl.x_lo.tolist(),
        "level_max": mdl.x_hi.tolist(),
        "gain_state": "[x; u_prev]" if rate else "x",
        "K": K.tolist(),
        "poles_z": _pairs(poles_z),
        "poles_s": _pairs([p for p in poles_s if math.isfinite(p.real)]),
    }


def _vec(values: list[float], fmt: str = ".4g") -> str:
    return "(" + ", ".join(format(v, fmt) for v in values) + ")"


def _poles(pairs: list[list[float]]) -> str:
    return "  " + "  ".join(f"{re:.6g}" if im == 0 else f"{re:.6g}{im:+.6g}i" for re, im in pairs)


def format_design(source: str, r: dict[str, Any]) -> str:
    """The design as text."""
    u = r["unit"]
    rate = "none" if r["rate_limit"] == 0 else f"{r['rate_limit']:g} V/s"
    lines = [
        f"MPC design: {source} ({r['plant']})",
        f"linearized at levels {_vec(r['x_e'])} {u}, pumps {_vec(r['u_e'])} V",
    ]
    if r["note"]:
        lines.append(f"note: {r['note']}")
    lines += [
        f"sampling time T = {r['sampling_time']:g} s, prediction step {r['prediction_step']:g} s, "
        f"horizon N = {r['horizon']} ({r['horizon'] * r['prediction_step']:g} s), control horizon "
        f"{r['control_horizon']}, preview {'on' if r['preview'] else 'off'}",
        f"weights: output {r['output_weight']:g}, input {r['input_weight']:g}, rate {r['rate_weight']:g} "
        f"(relative to the ranges); slack {r['slack_weight']:g}",
        f"  Q diag {_vec(r['Q_diag'])}  R diag {_vec(r['R_diag'])}  S diag {_vec(r['S_diag'])}",
        f"constraints: pumps {_vec(r['u_min'], 'g')}..{_vec(r['u_max'], '.3g')} V (hard), rate limit {rate}, "
        f"levels {_vec(r['level_min'], 'g')}..{_vec(r['level_max'], 'g')} {u} (soft)",
        f"estimator: Kalman filter on tanks {r['measured']}, {r['disturbance']} disturbances; tracked tanks "
        f"{r['tracked']}",
        f"unconstrained gain (the LQR, u = -K {r['gain_state']}) K =",
        "\n".join("  " + " ".join(f"{x:12.6g}" for x in row) for row in r["K"]),
        "closed-loop poles (z) at the prediction step =", _poles(r["poles_z"]),
        "closed-loop poles (s, rad/s) =", _poles(r["poles_s"]),
    ]
    return "\n".join(lines)


def compare(params: Any, plant: Any, d: Any, phase: float) -> dict[str, Any]:
    """MPC and (when the file has one for this plant) the PI matrix on the standard
    scenario; the figures of each as JSON values."""
    from quadtank_tui.core.controllers.matrix import ELEMENTS, ControllerMatrix, Family
    from quadtank_tui.core.controllers.mpc.predictive import MPC
    from quadtank_tui.core.controllers.mpc.simulate import figures, run_mpc, run_pi, standard_scenario

    mdl = d.model
    scn = standard_scenario(plant, mdl.x_e, phase=phase, lead=d.settings.horizon * d.prediction.T + 10.0)
    result: dict[str, Any] = {
        "steps": [[t, loop + 1, level] for t, loop, level in scn.steps],
        "leak": list(scn.leak) if scn.leak else None,
        "duration": scn.duration,
    }
    run = run_mpc(plant, MPC(d), mdl.x_e, scn)
    result["MPC"] = _figures_dict(figures(plant, run, scn, mdl.x_lo, mdl.x_hi))
    why = pi_missing(params, plant)
    if why:
        result["PI"] = None
        result["PI_missing"] = why
    else:
        family = Family.PID if params.control.family is Family.MPC else params.control.family  # its PID settings
        matrix = ControllerMatrix(params.tsamp, family, params.control.structure,
                                  pid={e: c.pid for e, c in zip(ELEMENTS, params.controllers)},
                                  general={e: c.general for e, c in zip(ELEMENTS, params.controllers)})
        pi = run_pi(plant, matrix, mdl.x_e, mdl.u_e, scn)
        result["PI"] = _figures_dict(figures(plant, pi, scn, mdl.x_lo, mdl.x_hi))
    result["verdict"] = verdict(result["MPC"], result["PI"])
    return result


def verdict(mpc: dict[str, Any], pi: dict[str, Any] | None) -> list[str]:
    """Per loop, whether the MPC's IAE is no worse than PI's, and where it is worse,
    why: on the announced steps or on the leak (which is not in the MPC's model: it
    is estimated as input disturbances, after the fact), and at what price PI's
    figure comes (its samples of a level beyond the limits the MPC keeps)."""
    if pi is None:
        return []
    out = []
    for i, (m, p) in enumerate(zip(mpc["iae"], pi["iae"])):
        ratio = m / p if p > 0 else math.inf
        head = f"loop {i + 1}: MPC IAE {m:.4g} against PI's {p:.4g} ({ratio:.2f} x)"
        if ratio <= 1.0 and mpc["violations"] == 0:
            out.append(head + ": no worse, no level beyond its limit")
            continue
        ms, ps = m - mpc["iae_leak"][i], p - pi["iae_leak"][i]
        ml, pl = mpc["iae_leak"][i], pi["iae_leak"][i]
        why = [f"steps {ms:.4g} against {ps:.4g}, leak {ml:.4g} against {pl:.4g}"]
        if ml > pl and ms <= ps:
            why.append("worse on the leak alone: the leak is not in the MPC's model (its Kalman filter "
                       "takes it for input disturbances, after the fact)")
        if pi["violations"] > 0:
            why.append(f"PI's figure comes with {pi['violations']} samples of a level beyond its limit, "
                       f"the MPC's with {mpc['violations']}: within the limits this setting reaches {m:.4g}")
        out.append(head + ": WORSE; " + "; ".join(why))
    return out


def _figures_dict(f: Any) -> dict[str, Any]:
    """Figures as strict JSON values (no solve times for PI: null, not NaN)."""
    from dataclasses import asdict

    return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in asdict(f).items()}


def pi_missing(params: Any, plant: Any) -> str:
    """Why the file's controllers cannot be compared on this plant ("" when they can)."""
    from quadtank_tui.core.controllers.matrix import Family

    if params.control.family is Family.STATE_FEEDBACK:
        return "the file's controller type is state feedback"
    if len(plant.inputs) < 2 or tuple(plant.controlled) != (0, 1):
        return f"the {plant.kind} plant is not wired as two loops (tank i by pump i)"
    if params.control.family is Family.PID and all(params.controllers[i].pid.K == 0 for i in (0, 3)):
        return "the file's controllers have zero gain"
    return ""


def _row(name: str, f: dict[str, Any] | None, loops: int) -> str:
    if f is None:
        return f"{name:<4} " + "-"
    iae = " ".join(f"{x:9.4g}" for x in f["iae"])
    leak = " ".join(f"{x:9.4g}" for x in f["iae_leak"])
    over = " ".join(f"{x:6.1f}" for x in f["overshoot"])
    times = "" if f["p50_ms"] is None else f"{f['p50_ms']:6.2f} {f['p99_ms']:6.2f}"
    return (f"{name:<4} {iae}  {leak}  {over}  {f['at_limit']:8.1f} {f['violations']:6d} {f['faults']:6d}  {times}")


def format_comparison(c: dict[str, Any]) -> str:
    """The comparison as a table (one row per controller)."""
    loops = len(c["steps"])
    steps = ", ".join(f"loop {loop} to {level:.4g} at {t:g} s" for t, loop, level in c["steps"])
    leak = f"; leak tank {c['leak'][1]} (area {c['leak'][2]:.3g}) at {c['leak'][0]:g} s" if c["leak"] else ""
    head_iae = " ".join(f"{'IAE' + str(i + 1):>9}" for i in range(loops))
    head_leak = " ".join(f"{'leak' + str(i + 1):>9}" for i in range(loops))
    head_over = " ".join(f"{'OS' + str(i + 1) + '%':>6}" for i in range(loops))
    lines = [
        f"nonlinear simulation, {c['duration']:g} s: {steps}{leak}",
        f"{'':<4} {head_iae}  {head_leak}  {head_over}  {'limit[s]':>8} {'viol':>6} {'fail':>6}  "
        f"{'p50ms':>6} {'p99ms':>6}",
        _row("MPC", c["MPC"], loops),
        _row("PI", c["PI"], loops) if c["PI"] is not None else f"PI   none: {c['PI_missing']}",
        "IAE: level unit x s over the run (leakN: over the leak); OS: overshoot of each step; "
        "limit: time a pump sat at 0 or full; viol: samples with a level beyond its limit",
        *c.get("verdict", []),
    ]
    return "\n".join(lines)
