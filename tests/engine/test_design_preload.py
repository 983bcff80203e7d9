"""A loop on a rig loads what a first state feedback or MPC design imports (scipy,
OSQP) on a thread of its own as it starts: imported on the loop's thread at the
first switch, it stalled the samples past the rig's watchdog (issue 26's Active
test saw the guard set the pumps to 0)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _loaded_after_start(daq: bool) -> list[str]:
    """In a fresh interpreter: build an engine (with a rig stand-in or without),
    wait for the preload, and say which design modules are loaded."""
    code = textwrap.dedent(f"""
        import sys, threading
        from quadtank_tui.engine.backend import ProcessBackend
        from quadtank_tui.engine.controllers import DESIGN_MODULES
        from quadtank_tui.engine.runner import build_engine

        class Rig(ProcessBackend):
            kind = "Active"
            def read_levels(self): return (0.5, 0.5, 0.1, 0.1)
            def write_pumps(self, u): pass
            def safe_state(self): pass

        build_engine(None, daq=Rig() if {daq} else None, clock="manual")
        for t in threading.enumerate():
            if t.name == "design-preload":
                t.join(60)
        print(" ".join(m for m in DESIGN_MODULES if m in sys.modules))
    """)
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return out.stdout.split()


def test_a_loop_on_a_rig_has_the_design_modules_loaded_before_a_switch() -> None:
    from quadtank_tui.engine.controllers import DESIGN_MODULES

    assert _loaded_after_start(daq=True) == list(DESIGN_MODULES)
    # the simulator alone keeps its start cheap: nothing is loaded before it is asked for
    assert "osqp" not in _loaded_after_start(daq=False)
