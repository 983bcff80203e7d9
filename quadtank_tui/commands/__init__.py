"""One module per `quadtank` subcommand (cli.py holds only the parser and the
dispatch), and what every command shares: UsageError, warn and say.  Here rather
than in cli.py, which imports these modules."""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, Iterable

if TYPE_CHECKING:
    from quadtank_tui.core.parameters import Parameters
    from quadtank_tui.files.log_reader import LogData


class UsageError(Exception):
    """Bad input from the command line or a file it names; the message says where."""


def warn(warnings: Iterable[str]) -> None:
    """Each warning of a file read (`.par`, `.log`) as one line on stderr."""
    for w in warnings:
        print(f"quadtank: warning: {w}", file=sys.stderr)


def say(line: str) -> None:
    """One line on stderr; after a hang-up the terminal is gone and writing to it
    fails (EIO), which must not turn a clean stop into a traceback."""
    try:
        print(line, file=sys.stderr, flush=True)
    except OSError:
        pass


def params_of(par: str | None) -> tuple[Parameters, str]:
    """The parameters of a `.par` file (its warnings on stderr) and its name, or the
    built-in preset without one."""
    from quadtank_tui.core.parameters import PRESET

    if par is None:
        return PRESET, "built-in preset"
    from quadtank_tui.files.par import read_par

    read = read_par(par)
    warn(read.warnings)
    return read.params, par


def read_sampled(path: str) -> tuple[LogData, float]:
    """A log and its sampling time (UsageError without one); its warnings on stderr."""
    from quadtank_tui.files.log_reader import read_log

    log = read_log(path)
    warn(log.warnings)
    if log.tsamp is None:
        raise UsageError(f"{path}: no TSamp in the header: the sampling time is needed")
    return log, log.tsamp


def pause_gc() -> None:
    """For a TUI's start-up, before the UI is imported: the start allocates a great
    many objects that live as long as the program (modules, classes, the screen's
    widgets), and the cyclic collector would scan them over and over, about 40 ms of
    the first frame (benchmarks/tui_cost.py).  The app built with `resume_gc=True`
    turns it back on after its first frame (ui.app.resume_gc)."""
    import gc

    gc.disable()
