"""`quadtank plot LOG [LOG ...] --out FILE.png|svg|pdf`: logged runs as a figure
for a report (files/figures/runs.py draws it).

Bad input - an unknown suffix, a variable a log lacks, a run without a step to
align at - is one line on stderr and exit status 2 (cli.main's handling of
ValueError), and no file is written.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from quadtank_tui.commands import UsageError, warn

if TYPE_CHECKING:
    from quadtank_tui.core.plants import Plant

#: files.figures.runs's choices, written out: that module loads matplotlib, which
#: building the parser must not (tests/cli/test_plot_cli.py checks they agree).
UNITS = ("cm", "V", "norm")
ALIGNS = ("logon", "step")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "plot", help="draw logged runs as a figure file (PNG, SVG, PDF) for a report",
        description="Draw one or more .log files as a figure: a panel per loop (y with its reference), "
        "the upper tanks, the pump inputs; several runs overlaid and aligned; each loop's step "
        "figures (rise, overshoot, settling, IAE) written beside it.  The same data give the same file.",
        epilog="Example: quadtank plot logs/pi.log logs/pid.log --out step.png --align step")
    p.add_argument("logs", nargs="+", metavar="LOG", help=".log files (overlaid, one colour each)")
    p.add_argument("--out", required=True, metavar="FILE", help="the figure: .png, .svg or .pdf")
    p.add_argument("--vars", metavar="NAMES", default=None,
                   help="comma-separated columns, e.g. y1,r1,u1 (default: those of y1,y2,r1,r2 logged)")
    p.add_argument("--units", choices=UNITS, default="cm",
                   help="levels in cm and pumps in V (default), everything in V, or normalized as logged")
    p.add_argument("--align", choices=ALIGNS, default="logon",
                   help="t = 0 at each log's first row (default) or at its first reference step")
    p.add_argument("--par", metavar="FILE",
                   help="the plant whose sensor gains turn levels into cm (default: the default parameters)")
    p.set_defaults(handler=run)


def _names(text: str | None) -> tuple[str, ...] | None:
    if text is None:
        return None
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    if not names:
        raise UsageError("--vars: no variable named (give e.g. y1,r1)")
    return names


def run(args: argparse.Namespace) -> int:
    from quadtank_tui.files.figures import figure_format

    figure_format(args.out)  # the suffix first: nothing is read for a name that cannot be written
    chosen = _names(args.vars)
    from quadtank_tui.commands.logview import times
    from quadtank_tui.files.log_reader import read_log
    from quadtank_tui.files.figures.runs import DEFAULT_VARS, Run, align, runs_figure, scales
    from quadtank_tui.files.figures.style import save

    logs = []
    for path in args.logs:
        log = read_log(path)
        warn(log.warnings)
        if log.rows < 2:
            raise UsageError(f"{path}: {log.rows} row(s): a plot needs two")
        logs.append((path, log))
    if chosen is None:
        names = tuple(n for n in DEFAULT_VARS if any(n in log.variables for _, log in logs))
        if not names:
            raise UsageError(f"{args.logs[0]}: none of {', '.join(DEFAULT_VARS)} logged; choose with --vars")
    else:
        names = chosen
        for path, log in logs:
            missing = [n for n in names if n not in log.variables]
            if missing:
                raise UsageError(f"{path}: no column {' '.join(missing)} (logged: {' '.join(log.variables)})")
    labels = _labels(args.logs)
    runs = [align(Run(label, times(log, path), log.columns()), args.align, path)
            for label, (path, log) in zip(labels, logs)]
    xlabel = "time since the first logged row (LogOn), s" if args.align == "logon" \
        else "time since the first reference step, s"
    fig = runs_figure(runs, names, scales(args.units, _plant(args.par)), xlabel=xlabel,
                      title=", ".join(args.logs) if len(args.logs) == 1 else "")
    print(f"wrote {save(fig, args.out)}")
    return 0


def _labels(paths: list[str]) -> list[str]:
    """Each run's name in the legend: the file name, or the path where two share a name."""
    names = [Path(p).name for p in paths]
    return [p if names.count(n) > 1 else n for p, n in zip(paths, names)]


def _plant(par: str | None) -> Plant:
    from quadtank_tui.core.parameters import PRESET

    if par is None:  # the quadruple tank with the thesis's sensors (kc = 0.5 V/cm)
        return PRESET.process_plant()
    from quadtank_tui.files.par import read_par

    read = read_par(par)
    warn(read.warnings)
    return read.params.process_plant()
