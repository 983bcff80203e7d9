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


def test_analyze_does_not_import_python_control() -> None:
    """`quadtank analyze` answered in 1.7 s, 1.3 s of it importing python-control and
    matplotlib for a 4-state zeros computation (issue 18); now 0.37 s."""
    import subprocess
    import sys

    code = (
        "import sys, io, contextlib\n"
        "from quadtank_tui.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    rc = main(['analyze', '--preset', 'nonminphase'])\n"
        "print(rc, 'control' in sys.modules, 'matplotlib' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["0", "False", "False"], out.stdout + out.stderr
