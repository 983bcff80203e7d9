"""What the Design screen looks like (golden SVGs under __snapshots__): P-'s
physical g11 with its candidates, and the 2x2 design with its check."""

from __future__ import annotations

import pytest

from uikit import make_app  # noqa: E402


@pytest.fixture
def app(engine):
    return make_app(engine)


async def _open(pilot, *keys: str) -> None:
    await pilot.pause()
    await pilot.press("d")
    for key in keys:
        await pilot.pause()
        await pilot.app.workers.wait_for_complete()
        await pilot.press(key)
    await pilot.pause()
    await pilot.app.workers.wait_for_complete()
    await pilot.pause()


def test_design_120x40_after_2x2_design(app, snap_compare) -> None:
    async def run_before(pilot) -> None:
        await _open(pilot, "2")

    assert snap_compare(app, terminal_size=(120, 40), run_before=run_before)


def test_design_80x24(app, snap_compare) -> None:
    assert snap_compare(app, terminal_size=(80, 24), run_before=_open)
