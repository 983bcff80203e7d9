"""The `quadtank` command: subcommands for analysis (and, as they land, the TUI,
headless runs, logs and the virtual rig).

Every subcommand turns bad input into one clear line on stderr and exit status 2;
a traceback never reaches the user.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Callable, Sequence

from quadtank_tui.core.analysis import analyze, format_report
from quadtank_tui.core.plant import SETTINGS, PlantError, steady_state_levels


class UsageError(Exception):
    """Bad input from the command line or a file it names; the message says where."""


Handler = Callable[[argparse.Namespace], int]


def _add_analyze(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "analyze",
        help="linearize a setting: time constants, G(s), zeros, phase, RGA",
        description="Linearize the quadruple-tank process at an operating point and "
        "print its time constants, transfer matrix, transmission zeros, phase and RGA.",
    )
    p.add_argument(
        "--preset", choices=sorted(SETTINGS), default="minphase",
        help="named physical setting (default: minphase, the paper's P-)",
    )
    p.add_argument(
        "--at", choices=("levels", "steady"), default="levels",
        help="linearize at the setting's operating levels (default) or at the steady "
        "state of its pump voltages",
    )
    p.add_argument("--json", action="store_true", help="print a JSON object instead of a table")
    p.set_defaults(handler=_cmd_analyze)


def _cmd_analyze(args: argparse.Namespace) -> int:
    setting = SETTINGS[args.preset]
    params, h0 = setting.params, setting.op.h
    where = "operating levels"
    if args.at == "steady":
        h0 = steady_state_levels(setting.op.v, params)
        where = f"steady state of v = ({setting.op.v[0]:.2f}, {setting.op.v[1]:.2f}) V"
    result = analyze(params, h0)
    if args.json:
        out = {"setting": setting.name, "linearized_at": args.at, **result.to_dict()}
        print(json.dumps(out, indent=2))
    else:
        print(format_report(f"{setting.title}, linearized at the {where}", result))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="quadtank",
        description="Run and analyse the quadruple-tank laboratory process.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    _add_analyze(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    handler: Handler | None = getattr(args, "handler", None)
    if handler is None:
        # No TUI yet: show the analysis of the default setting.
        handler = _cmd_analyze
        args = parser.parse_args(["analyze", *(argv or [])[:0]])
    try:
        return handler(args)
    except (UsageError, PlantError, OSError, ValueError) as exc:
        print(f"quadtank: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("quadtank: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
