"""Layering: the core never imports the DAQ package; reading a DAQ configuration
pulls in neither pymodbus nor asyncio nor the UI (a bad file is reported at once,
and a program without a DAQ never loads the protocol stack)."""

from __future__ import annotations

import json
import subprocess
import sys


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
                       "quadtank_tui.daq.registers", "quadtank_tui.core.calibration")
    bad = [m for m in mods if m.split(".")[0] in ("pymodbus", "asyncio", "textual", "rich")]
    assert bad == []


def test_core_does_not_import_daq() -> None:
    code = (
        "import pkgutil, importlib, sys, quadtank_tui.core as core\n"
        "for m in pkgutil.walk_packages(core.__path__, 'quadtank_tui.core.'):\n"
        "    importlib.import_module(m.name)\n"
        "print(any(n.startswith('quadtank_tui.daq') or n.startswith('pymodbus') for n in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
