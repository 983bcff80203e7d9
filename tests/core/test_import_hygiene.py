"""The core is pure (style.md habit 1): importing it must not pull in the UI stack."""

from __future__ import annotations

import json
import subprocess
import sys

FORBIDDEN = ("textual", "rich", "plotext", "asyncio")


def test_core_imports_no_ui_or_asyncio() -> None:
    code = (
        "import json, pkgutil, importlib, sys\n"
        "import quadtank_tui.core as core\n"
        "for m in pkgutil.walk_packages(core.__path__, 'quadtank_tui.core.'):\n"
        "    importlib.import_module(m.name)\n"
        f"print(json.dumps(sorted(n for n in sys.modules if n.split('.')[0] in {FORBIDDEN!r})))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    leaked = json.loads(out.stdout)
    assert leaked == [], f"quadtank_tui.core imported {leaked}"
