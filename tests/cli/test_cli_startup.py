"""Start-up: building the `quadtank` parser loads none of the heavy stacks; each
subcommand imports what it runs (python-control and scipy took ~2 s of every
command, `--help` and the TUI's start included)."""

from __future__ import annotations

import json
import subprocess
import sys


def test_the_parser_loads_no_heavy_module() -> None:
    code = ("import json, sys\nfrom quadtank_tui.cli import build_parser\nbuild_parser()\n"
            "print(json.dumps(sorted(sys.modules)))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    loaded = {m.split(".")[0] for m in json.loads(out.stdout)}
    assert loaded & {"control", "scipy", "numpy", "pymodbus", "asyncio", "textual"} == set()
