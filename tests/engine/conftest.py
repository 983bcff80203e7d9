"""Engines for tests: no thread, unpaced virtual time, folders under tmp_path."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.engine.runner import Engine, build_engine


@pytest.fixture
def make_engine(tmp_path: Path) -> Callable[..., Engine]:
    made: list[Engine] = []

    def make(**kwargs: object) -> Engine:
        kwargs.setdefault("clock", "manual")
        kwargs.setdefault("params_dir", tmp_path / "params")
        kwargs.setdefault("logs_dir", tmp_path / "logs")
        engine = build_engine(**kwargs)  # type: ignore[arg-type]
        made.append(engine)
        return engine

    yield make
    for engine in made:
        engine.stop()
