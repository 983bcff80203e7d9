"""`quadtank log`: inspect a `.log` file (info), export it (.mat, .csv); its plot and
compare actions are commands/logview.py's."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from quadtank_tui.commands import UsageError, logview, warn


#: files.export.FORMATS, written out because that module loads scipy.io just for
#: the parser's choices (tests/cli/test_files_cli.py checks they agree).
EXPORT_FORMATS = ("mat", "csv")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("log", help="inspect, plot, compare or export .log data files",
                       description="Inspect a .log data file, plot it in the terminal, compare two "
                       "runs' step figures, or export it to .mat / .csv.")
    logsub = p.add_subparsers(dest="log_command", metavar="ACTION", required=True)
    info = logsub.add_parser("info", help="variables, TSamp, rows and duration of a log")
    info.add_argument("file", metavar="FILE")
    info.set_defaults(handler=_cmd_log_info)
    exp = logsub.add_parser("export", help="write a log as .mat (one variable per column + TSamp) or .csv")
    exp.add_argument("file", metavar="FILE")
    exp.add_argument("--to", choices=EXPORT_FORMATS, required=True, help="output format")
    exp.add_argument("--out", metavar="PATH", help="output file (default: FILE with the format's suffix)")
    exp.add_argument("--force", action="store_true", help="overwrite the output file if it exists")
    exp.set_defaults(handler=_cmd_log_export)
    logview.add_parsers(logsub)


def _cmd_log_info(args: argparse.Namespace) -> int:
    from quadtank_tui.files.log_writer import format_tsamp
    from quadtank_tui.files.log_reader import read_log

    log = read_log(args.file)
    warn(log.warnings)
    tsamp = "unknown" if log.tsamp is None else f"{format_tsamp(log.tsamp)} s"
    duration = "unknown" if log.duration is None else f"{log.duration:g} s"
    print(f"file       {args.file}")
    print(f"created    {log.created_text or 'unknown'}")
    print(f"variables  {' '.join(log.variables)}")
    print(f"TSamp      {tsamp}")
    print(f"rows       {log.rows}")
    print(f"duration   {duration}")
    return 0


def _same_file(a: str, b: str) -> bool:
    """Whether two paths name one file (a link too); a path that cannot be looked
    up (missing, a symlink loop) is not the log.  Path.resolve() raised RuntimeError
    on a symlink loop, a traceback instead of an error line."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _cmd_log_export(args: argparse.Namespace) -> int:
    from quadtank_tui.files.export import export_log
    from quadtank_tui.files.log_reader import read_log

    log = read_log(args.file)
    warn(log.warnings)
    out = args.out or str(Path(args.file).with_suffix("." + args.to))
    if _same_file(out, args.file):
        raise UsageError(f"{out}: the export would overwrite the log itself; give --out")
    try:
        print(export_log(log, out, args.to, overwrite=args.force))
    except FileExistsError:
        raise UsageError(f"{out} exists; give --force to overwrite it") from None
    return 0
