"""Faults through the engine: the command, the status, the log's `%` lines, the
script event and Murray-Smith's drain test as shipped (issue 14)."""

from __future__ import annotations

from pathlib import Path

import pytest

from quadtank_tui.cli import main
from quadtank_tui.engine.commands import LogOn, SetFault, SetState
from quadtank_tui.files.log_reader import read_log
from quadtank_tui.files.script import ScriptError, parse_script

PARAMS = Path(__file__).resolve().parents[2] / "params"


def test_set_fault_status_and_log_comment(make_engine, tmp_path: Path) -> None:
    e = make_engine()
    assert e.submit(LogOn()).result().ok
    assert e.submit(SetState("Run")).result().ok
    e.step(10)
    assert e.submit(SetFault("leak", 1, 0.02)).result().ok
    e.step(1)
    assert e.snapshot().faults == "leak tank 1 (0.02)"
    refused = e.submit(SetFault("leak", 9, 0.02)).result()
    assert not refused.ok and "tank must be 1..4" in refused.message
    assert not e.submit(SetFault("clog", 2, on=False)).result().ok  # was not on
    e.step(10)
    assert e.submit(SetFault("leak", 1, on=False)).result().ok
    e.step(1)
    assert e.snapshot().faults == ""
    e.loop.log.stop()
    text = next((tmp_path / "logs").glob("*.partial")).read_text()
    comments = [ln for ln in text.splitlines()[3:] if ln.startswith("%")]
    assert comments == ["% t = 1 s: fault on: leak tank 1 (0.02)", "% t = 2.1 s: fault off: leak 1"]


def test_script_fault_events() -> None:
    s = parse_script("- at: 5\n  fault: {kind: clog, target: 2, value: 0.7}\n"
                     "- at: 9\n  fault: {kind: clog, target: 2, on: off}\n")
    assert [e.value for e in s.events] == [("clog", 2, 0.7, True), ("clog", 2, 0.0, False)]
    for bad, msg in (("{kind: flood, target: 1}", "fault.kind"), ("{kind: leak}", "fault needs"),
                     ("{kind: leak, target: 0}", "fault.target"), ("{kind: leak, target: 1, on: maybe}", "fault.on")):
        with pytest.raises(ScriptError, match=msg):
            parse_script(f"- at: 1\n  fault: {bad}\n")


def test_shipped_drain_test(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Murray-Smith's Figure 22: the drain of tank 2 partly closed at 100 s, reopened
    at 300 s. H2 rises while pump 2 backs off and returns; H1 hardly moves (the tank-2
    transient is the larger, as he reports); both are back at their references."""
    out = tmp_path / "drain.log"
    assert main(["run", "--par", str(PARAMS / "coupled-tito.par"), "--script",
                 str(PARAMS / "murray-smith-drain.yaml"), "--duration", "500", "--log", str(out)]) == 0
    text = out.read_text()
    assert "% t = 100 s: fault on: clog tank 2 (0.7)" in text and "% t = 300 s: fault off: clog 2" in text
    log = read_log(out)
    y1, y2, u2 = log["y1"], log["y2"], log["u2"]
    r1, r2 = 0.663267, 0.549945
    assert abs(y1[990] - r1) < 1e-4 and abs(y2[990] - r2) < 1e-4  # settled before the closure
    rise = y2[1000:3000].max() - r2
    dip = r2 - y2[3000:].min()
    assert 0.005 < rise < 0.03 and 0.005 < dip < 0.03  # a few mm of H2 (1 V = 3 cm)
    assert abs(y1[1000:] - r1).max() < 0.2 * rise
    assert u2[2990] < u2[990] - 0.1  # pump 2 passes less while the drain is half shut
    assert abs(y1[-1] - r1) < 1e-4 and abs(y2[-1] - r2) < 1e-4


def test_status_line_names_the_active_faults(make_engine) -> None:
    from quadtank_tui.ui.widgets.status_line import StatusLine

    e = make_engine()
    assert e.submit(SetFault("sensor_stuck", 2)).result().ok
    e.step(1)
    assert StatusLine().numbers(e.snapshot()).endswith("faults: sensor stuck sensor 2")
