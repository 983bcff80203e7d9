"""Fixtures of the Setup screen's UI tests: an engine on a private `params/`
folder (the shipped files), and the app showing the Setup screen on it."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from setup_app import SetupApp  # noqa: E402
from setup_fake_engine import SetupFakeEngine  # noqa: E402


@pytest.fixture
def engine(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> SetupFakeEngine:
    # Relative folders, so messages read "params/x.par" whatever tmp_path is.
    monkeypatch.chdir(tmp_path)
    return SetupFakeEngine(Path("params"))


@pytest.fixture
def app(engine: SetupFakeEngine) -> SetupApp:
    return SetupApp(engine)
