"""`quadtank statefb`: print the state-feedback design a `.par` file asks for.

The design is the one the loop would run (core.controllers.statefb.quadtank.design_for): the
ZOH model Phi, Gamma at the sampling time, the poles (s and z), the gains L1, L2 and
the robustness delta.  --ts and --sampling override the file's settling time and
sampling time; errors are one line naming the file or the option.  The design stack
(numpy, scipy) loads inside the handler, so other commands do not pay for it.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from quadtank_tui.commands import params_of


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "statefb",
        help="state-feedback design of a .par file: Phi, Gamma, poles, L1, L2, delta",
        description="Design the state-feedback tracking controller (Desautel, chapters 3-4) "
        "that the .par file's STATE FEEDBACK section asks for, on its plant in use (its PLANT "
        "section, else the SIMULATION quadruple tank), and "
        "print the ZOH model, the poles, the gains and the robustness delta.",
    )
    p.add_argument("--par", metavar="FILE",
                   help="a .par file (default: the built-in preset, the paper's P-)")
    p.add_argument("--ts", metavar="SECONDS", type=float,
                   help="settling time, s (overrides STATE FEEDBACK.Ts)")
    p.add_argument("--sampling", metavar="SECONDS", type=float,
                   help="sampling time, s (overrides SAMPLING TIME.TSamp)")
    p.add_argument("--json", action="store_true",
                   help="print a JSON object (keys Phi, Gamma, poles, L1, L2, delta, ...)")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from quadtank_tui.core.parameters import STATEFB_SECTION, TSAMP, TSAMP_MAX_MS, TSAMP_MIN_MS
    from quadtank_tui.core.controllers.statefb.in_use import design_in_use
    from quadtank_tui.core.ranges import ParameterError

    params, source = params_of(args.par)
    changes: dict[str, Any] = {}
    if args.ts is not None:
        changes[f"{STATEFB_SECTION}.Ts"] = args.ts
    if args.sampling is not None:
        changes[TSAMP] = args.sampling * 1000.0
    try:
        params = params.with_values(changes)
    except ParameterError as exc:
        if exc.field == TSAMP:
            raise ValueError(f"--sampling: {args.sampling:g} s is outside "
                             f"{TSAMP_MIN_MS / 1000:g}..{TSAMP_MAX_MS / 1000:g} s") from None
        option = "--ts" if exc.field.endswith(".Ts") else exc.field
        raise ValueError(f"{option}: {exc.reason} s") from None
    try:
        d = design_in_use(params)  # the plant in use: a PLANT section counts
    except ParameterError as exc:
        raise ValueError(f"{source}: {exc}") from None
    result = design_dict(d, params.statefb.poles)
    print(json.dumps({"source": source, **result}, indent=2) if args.json else format_design(source, result))
    return 0


def _pairs(values: Any) -> list[list[float]]:
    return [[complex(v).real, complex(v).imag] for v in values]


def design_dict(d: Any, poles_setting: str) -> dict[str, Any]:
    """The design as plain JSON values; `poles` are the placed z-poles as [re, im]."""
    return {
        "sampling_time": d.T,
        "x_e": d.model.x_e.tolist(),
        "u_e": d.model.u_e.tolist(),
        "poles_setting": poles_setting,
        "Phi": d.Phi.tolist(),
        "Gamma": d.Gamma.tolist(),
        "poles_s": _pairs(d.poles_s),
        "poles": _pairs(d.placed_poles()),
        "L1": d.L1.tolist(),
        "L2": d.L2.tolist(),
        "delta": d.delta,
    }


def _matrix(rows: list[list[float]]) -> str:
    return "\n".join("  " + " ".join(f"{x:12.6g}" for x in r) for r in rows)


def _poles(pairs: list[list[float]]) -> str:
    return "  " + "  ".join(f"{re:.6g}" if im == 0 else f"{re:.6g}{im:+.6g}i" for re, im in pairs)


def format_design(source: str, r: dict[str, Any]) -> str:
    """The design as text, one block per quantity."""
    lines = [
        f"State-feedback design: {source}",
        "linearized at h = (" + ", ".join(f"{x:.3f}" for x in r["x_e"]) + ") cm, u_e = ("
        + ", ".join(f"{u:.4f}" for u in r["u_e"]) + ") V",
        f"sampling time T = {r['sampling_time']:g} s, poles: {r['poles_setting']}",
        "Phi =", _matrix(r["Phi"]),
        "Gamma =", _matrix(r["Gamma"]),
        "poles (s, rad/s) =", _poles(r["poles_s"]),
        "poles (z, placed) =", _poles(r["poles"]),
        "L1 =", _matrix(r["L1"]),
        "L2 =", _matrix(r["L2"]),
        f"delta = {r['delta']:.4f}  (1/||G||inf, discrete loop from w to v)",
    ]
    return "\n".join(lines)
