"""The lab's rules load nothing heavy: `quadtank lab`, the lock taken before a run
and the session process's checks must not pull in the UI, asyncio or the Modbus stack."""

from __future__ import annotations

import json
import subprocess
import sys


def test_rules_import_no_ui_asyncio_or_modbus() -> None:
    code = ("import json, sys\n"
            "import quadtank_tui.session.lab, quadtank_tui.session.roles\n"
            "import quadtank_tui.session.policy, quadtank_tui.session.lock\n"
            "print(json.dumps(sorted(sys.modules)))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    mods = json.loads(out.stdout)
    assert [m for m in mods if m.split(".")[0] in ("textual", "rich", "asyncio", "pymodbus", "numpy")] == []
