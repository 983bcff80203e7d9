"""Atomic saves follow the umask (issue 17.10): a `.par` saved by one lab user is
readable by the others when the umask says so, as a file made by open() is."""

from __future__ import annotations

import os
import stat
from datetime import datetime
from pathlib import Path
from typing import Iterator

import pytest

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.files.atomic import atomic_write_bytes, current_umask
from quadtank_tui.files.par import write_par


@pytest.fixture
def umask() -> Iterator[None]:
    saved = os.umask(0o022)
    yield
    os.umask(saved)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def test_a_saved_par_follows_the_umask(tmp_path: Path, umask: None) -> None:
    assert current_umask() == 0o022
    write_par(tmp_path / "mine.par", PRESET, created=datetime(2026, 1, 5, 9, 0, 0))
    assert _mode(tmp_path / "mine.par") == 0o644  # -rw-r--r--, as open() makes it
    os.umask(0o077)
    atomic_write_bytes(tmp_path / "private.par", b"x")
    assert _mode(tmp_path / "private.par") == 0o600


def test_a_replaced_file_keeps_its_mode(tmp_path: Path, umask: None) -> None:
    path = tmp_path / "shared.par"
    path.write_bytes(b"old")
    path.chmod(0o664)
    atomic_write_bytes(path, b"new")
    assert path.read_bytes() == b"new" and _mode(path) == 0o664
