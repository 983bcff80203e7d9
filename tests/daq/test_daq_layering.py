"""Layering: the core never imports the DAQ package; reading a DAQ configuration
pulls in neither pymodbus nor asyncio nor the UI (a bad file is reported at once,
and a program without a DAQ never loads the protocol stack)."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import quadtank_tui.core


def imported_by(*modules: str) -> list[str]:
    code = (
        "import json, sys\n"
        + "".join(f"import {m}\n" for m in modules)
        + "print(json.dumps(sorted(sys.modules)))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def test_config_and_calibration_do_not_load_the_link() -> None:
    mods = imported_by("quadtank_tui.daq.config", "quadtank_tui.daq.interlock",
                       "quadtank_tui.daq.registers", "quadtank_tui.core.calibration.fits")
    bad = [m for m in mods if m.split(".")[0] in ("pymodbus", "asyncio", "textual", "rich")]
    assert bad == []


def test_core_does_not_import_daq() -> None:
    """Statically (every import statement of every core module), so it costs no
    interpreter start; the core's own hygiene test covers what it loads at run time."""
    core = Path(quadtank_tui.core.__file__).parent
    offenders = []
    for path in sorted(core.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else (
                [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            offenders += [f"{path.name}: {n}" for n in names if n.startswith(("quadtank_tui.daq", "pymodbus"))]
    assert offenders == []
