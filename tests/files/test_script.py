"""Experiment scripts: what is accepted, and errors that name file, event and line."""

from __future__ import annotations

from pathlib import Path

import pytest

from quadtank_tui.files.script import ScriptError, parse_script, read_script

SAMPLE = Path(__file__).resolve().parents[2] / "params" / "sample_session.yaml"


def test_the_shipped_sample_session_reads() -> None:
    script = read_script(SAMPLE)
    actions = [(e.at, e.action) for e in script.events]
    assert actions == [(0.0, "mode"), (0.0, "set"), (0.0, "state"), (600.0, "log"),
                       (600.0, "mode"), (610.0, "step")]
    first_set = script.events[1]
    assert first_set.value["CONTROLLER ONE.K"] == 3.0 and first_set.value["CONTROLLER FOUR.Ti"] == 40.0
    assert first_set.value["CONTROLLER ONE.I"] is True and first_set.value["SAMPLING TIME.TSamp"] == 1000.0
    assert script.events[-1].value == {"REFERENCE ONE.Mean": 0.1}


def test_events_sort_by_time_keeping_file_order() -> None:
    s = parse_script("- {at: 5, state: Pause}\n- {at: 1, log: on}\n- {at: 1, log: off}\n"
                     "- {at: 2, add_water: {tank: 4, amount: -0.02}}\n- {at: 0, mode: automatic}\n")
    assert [(e.at, e.action, e.value, e.index) for e in s.events] == [
        (0.0, "mode", "Automatic", 5), (1.0, "log", "on", 2), (1.0, "log", "off", 3),
        (2.0, "add_water", (4, -0.02), 4), (5.0, "state", "Pause", 1)]
    assert parse_script("").events == ()


@pytest.mark.parametrize("text, message", [
    ("- at: 0\n  set: {\"CONTROLLER ONE.Kp\": 1}\n", "event 1 (line 1): unknown parameter 'CONTROLLER ONE.Kp'"),
    ("- at: 0\n  state: Run\n- at: 3\n  set: {\"CONTROLLER ONE.K\": abc}\n",
     "event 2 (line 3): CONTROLLER ONE.K: must be a number"),
    ("- at: -1\n  state: Run\n", "event 1 (line 1): 'at' must be a number of seconds >= 0"),
    ("- state: Run\n", "event 1 (line 1): no 'at'"),
    ("- {at: 0, state: Walk}\n", "state must be one of Run, Pause, Reset"),
    ("- {at: 0, state: Run, mode: Manual}\n", "one action per event, got 2"),
    ("- {at: 0, jump: 1}\n", "unknown action 'jump'"),
    ("- {at: 0, add_water: {tank: 5, amount: 0.1}}\n", "add_water.tank must be 1..4"),
    ("- {at: 0, step: {\"REFERENCE ONE.Wave\": 1}}\n", "step adds to a number"),
    ("- {at: 0, log: maybe}\n", "log must be one of on, off"),
    ("at: 0\n", "a script is a list of events"),
    ("- at: 0\n  set: [1, 2\n", "not valid YAML"),
])
def test_bad_scripts_are_refused_with_where_and_why(text: str, message: str) -> None:
    with pytest.raises(ScriptError) as err:
        parse_script(text, name="exp.yaml")
    assert str(err.value).startswith("exp.yaml") and message in str(err.value)


def test_missing_file() -> None:
    with pytest.raises(ScriptError, match="nope.yaml: no such file"):
        read_script("nope.yaml")


@pytest.mark.parametrize("text, message", [
    ('- at: 0\n  set: {"REFERENCE ONE.Mean": 1' + "0" * 400 + "}\n",
     "REFERENCE ONE.Mean: must be a finite number, got a whole number of 401 digits"),
    ("- at: 1" + "0" * 400 + "\n  state: Run\n", "'at' must be a number of seconds >= 0"),
    ("- {at: 0, add_water: {tank: 1, amount: 1" + "0" * 400 + "}}\n", "add_water.amount must be a number"),
    ("- {at: 0, fault: {kind: leak, target: 1, value: 1" + "0" * 400 + "}}\n", "fault.value must be a number"),
])
def test_a_number_too_large_for_a_float_is_refused_not_a_traceback(text: str, message: str) -> None:
    """Found by benchmarks/hardening.py (700 mutated scripts): YAML reads 400 digits as
    an int, and math.isfinite raised OverflowError on it."""
    with pytest.raises(ScriptError) as err:
        parse_script(text, name="exp.yaml")
    assert str(err.value).startswith("exp.yaml") and message in str(err.value)
