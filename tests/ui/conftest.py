"""Shared pieces of the UI tests: a deterministic app on a test engine."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from fake_engine import FakeEngine  # noqa: E402

from quadtank_tui.ui.app import QuadTankApp, build_app  # noqa: E402


def make_app(engine: object) -> QuadTankApp:
    """The app as the CLI builds it, with a fixed wall clock (the status line's
    "last sample ... ago" must not depend on when the test runs)."""
    return build_app(engine, refresh_interval=0.05, wall_clock=lambda: 0.0)  # type: ignore[arg-type]


@pytest.fixture
def fake() -> FakeEngine:
    return FakeEngine()
