"""A minimal app that shows the Setup screen on an engine, for tests and for
reading the screen in a terminal: `python tests/ui/setup_app.py [folder]` runs a
real-time simulation on `folder/params` (the shipped files if it has none)."""

from __future__ import annotations

import sys
from pathlib import Path

from textual.app import App

from quadtank_tui.engine.handle import EngineHandle
from quadtank_tui.ui.screens.setup import SetupScreen

STYLES = Path(__file__).resolve().parents[2] / "quadtank_tui" / "ui" / "styles"


class SetupApp(App[None]):
    CSS_PATH = [STYLES / "app.tcss", STYLES / "windows.tcss"]

    def __init__(self, engine: EngineHandle, *, open_setup: bool = True) -> None:
        super().__init__()
        self.engine = engine
        self.open_setup = open_setup

    def on_mount(self) -> None:
        if self.open_setup:
            self.push_screen(SetupScreen(self.engine, on_main=self.exit))


if __name__ == "__main__":  # pragma: no cover - for reading the screen by hand in a terminal
    import os

    from quadtank_tui.engine.runner import build_engine
    from quadtank_tui.files.shipped import write_shipped

    os.chdir(sys.argv[1] if len(sys.argv) > 1 else "/tmp")
    if not Path("params").exists():
        write_shipped("params")
    engine = build_engine(clock="virtual", speed=1.0, params_dir="params", logs_dir="logs")
    engine.start()
    from quadtank_tui.engine.commands import SetParams, SetState

    engine.submit(SetParams({"REFERENCE ONE.Mean": 0.33}))  # something to watch
    engine.submit(SetState("Run"))
    try:
        SetupApp(engine).run()
    finally:
        engine.stop()
