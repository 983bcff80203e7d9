"""The files layer imports the core only: never textual, asyncio, the engine or
the UI (checked in a fresh interpreter, so other tests' imports do not hide it)."""

from __future__ import annotations

import subprocess
import sys

MODULES = ["quadtank_tui.files.par", "quadtank_tui.files.log_writer", "quadtank_tui.files.log_reader", "quadtank_tui.files.export",
           "quadtank_tui.files.shipped", "quadtank_tui.core.parameters"]


def test_files_layer_imports_no_ui_no_asyncio() -> None:
    code = (
        "import sys\n"
        + "".join(f"import {m}\n" for m in MODULES)
        + "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('textual', 'rich', 'plotext', 'asyncio')"
        " or m.startswith(('quadtank_tui.engine', 'quadtank_tui.ui')))\n"
        "print(' '.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
