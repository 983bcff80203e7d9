"""A session designs a new MPC on a thread of its own (engine/design_ahead.py): the
first switch imports scipy and OSQP and designs, about 2 s on a loaded machine,
which on the driver's thread stalled the samples; now they go on, and the switch
happens between two samples once the design is done."""

from __future__ import annotations

import time
from typing import Any

import pytest
from sessionkit import ThreadSession

from quadtank_tui.engine import commands as c
from quadtank_tui.engine import controllers
from quadtank_tui.session.client import SessionClient

H = 0.5  # s: the sampling time (a long one, so a loaded machine's own gaps stay well inside 2 H)
DESIGN = 2.5  # s the design takes here (the first switch, measured 1.9-2.1 s)


def test_the_samples_go_on_while_the_first_mpc_is_designed(thread_session, monkeypatch: pytest.MonkeyPatch) -> None:
    import osqp  # noqa: F401 - loaded already: the design's time is the sleep below, the same every run
    import quadtank_tui.engine.mpc_control  # noqa: F401

    real = controllers.new_mpc

    def slow(*args: Any, **kw: Any) -> Any:
        time.sleep(DESIGN)
        return real(*args, **kw)

    monkeypatch.setattr(controllers, "new_mpc", slow)
    s: ThreadSession = thread_session(speed=1.0, tsamp_ms=H * 1000)
    walls: list[float] = []
    take = s.engine.sample

    def timed() -> int:  # when the driver takes each sample (the loop's own attributes stay the loop's)
        walls.append(time.monotonic())
        return take()  # the sampling slots the sample stands for, which the driver counts

    monkeypatch.setattr(s.engine, "sample", timed)
    with SessionClient(s.path) as client:
        assert client.submit(c.SetState("Run")).result(10).ok
        deadline = time.monotonic() + 10
        while len(walls) < 3 and time.monotonic() < deadline:
            time.sleep(0.05)
        first = len(walls)
        said = client.submit(c.SetParams({"CONTROL.Type": "MPC"})).result(30)
        assert said.ok, said.message
        switched = len(walls)
        assert s.engine.snapshot().mpc is not None and s.engine.snapshot().params.control.family.value == "MPC"
        while len(walls) < switched + 2 and time.monotonic() < deadline + 30:
            time.sleep(0.05)
        assert client.submit(c.SetState("Pause")).result(10).ok
    around = walls[first - 1:]
    gaps = [b - a for a, b in zip(around, around[1:])]
    assert switched - first >= DESIGN / H - 2, (first, switched)  # it sampled while designing
    assert max(gaps) <= 2 * H, (gaps.index(max(gaps)), switched - first, gaps)  # and no sample waited for the design (before: one gap of 2.5 s)
