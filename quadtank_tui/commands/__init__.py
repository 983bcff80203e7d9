"""One module per `quadtank` subcommand that grew beyond a handler in cli.py, and
the two helpers every command shares (cli.py, daq/cli.py and the modules here):
UsageError and warn.  Here rather than in cli.py, which imports these modules."""

from __future__ import annotations

import sys
from typing import Iterable


class UsageError(Exception):
    """Bad input from the command line or a file it names; the message says where."""


def warn(warnings: Iterable[str]) -> None:
    """Each warning of a file read (`.par`, `.log`) as one line on stderr."""
    for w in warnings:
        print(f"quadtank: warning: {w}", file=sys.stderr)
