"""A minimal app that shows the Setup screen on an engine, for tests and for
reading the screen in a terminal: `python tests/ui/setup_app.py [params_dir]`."""

from __future__ import annotations

import sys
from pathlib import Path

from textual.app import App

from quadtank_tui.engine.handle import EngineHandle
from quadtank_tui.ui.screens.setup import SetupScreen

STYLES = Path(__file__).resolve().parents[2] / "quadtank_tui" / "ui" / "styles"


class SetupApp(App[None]):
    CSS_PATH = [STYLES / "app.tcss", STYLES / "windows.tcss"]

    def __init__(self, engine: EngineHandle) -> None:
        super().__init__()
        self.engine = engine

    def on_mount(self) -> None:
        self.push_screen(SetupScreen(self.engine, on_main=self.exit))


if __name__ == "__main__":  # pragma: no cover - for reading the screen by hand
    sys.path.insert(0, str(Path(__file__).parent))
    from setup_fake_engine import SetupFakeEngine

    SetupApp(SetupFakeEngine(Path(sys.argv[1] if len(sys.argv) > 1 else "/tmp/setup-params"))).run()
