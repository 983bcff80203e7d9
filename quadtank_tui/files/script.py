"""Scripted experiments: a YAML list of timed events (B8, `quadtank run --script`).

Each event is a mapping with ``at`` (seconds since the start of the run) and exactly
one action::

    - at: 0
      set: {"CONTROLLER ONE.K": 3.0, "SAMPLING TIME.TSamp": 1000}
    - at: 0
      state: Run                  # Run | Pause | Reset
    - at: 600
      mode: Automatic             # Manual | Automatic (bumpless, as in the UI)
    - at: 600
      log: on                     # on | off
    - at: 610
      step: {"REFERENCE ONE.Mean": 0.1}   # add to a number's current value
    - at: 900
      add_water: {tank: 1, amount: 0.05}  # normalized level, Simul only
    - at: 1000
      fault: {kind: clog, target: 2, value: 0.5}   # Simul only (core.faults)
    - at: 1200
      fault: {kind: clog, target: 2, on: off}      # switch it off again
    - at: 1300
      disturbance: {d1: 0.5, d2: 0}   # the disturbance pumps, 0..1 of full PWM (an IST rig in Active; Simul: inflow into tanks 1, 2)
    - at: 1400
      inputs_from: logs/rig.log   # Manual, the pumps driven by the log's u1, u2 row by row

Keys are the `.par` "SECTION.Key" names.  Everything that can be checked without
running is checked here: unknown keys, values of the wrong kind, times, actions; a
problem is a :class:`ScriptError` naming the file, the event (1-based) and its line.
Ranges that depend on the state at the time (a period against a sampling time set
later) are checked when the event is applied, with the same naming.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping


from quadtank_tui.core.parameters import Kind, spec
from quadtank_tui.core.ranges import ParameterError, is_finite_number
from quadtank_tui.files.names import check_names
from quadtank_tui.files.yamltext import parse_yaml, read_text

ACTIONS = ("mode", "state", "set", "step", "add_water", "log", "fault", "disturbance", "inputs_from")
MODES = ("Manual", "Automatic")
STATES = ("Run", "Pause", "Reset")


class ScriptError(ValueError):
    """A refused script or event; the message names file, event, line and key."""

    def __init__(self, file: str, reason: str, event: int | None = None, line: int | None = None) -> None:
        where = file
        if event is not None:
            where += f", event {event}"
        if line is not None:
            where += f" (line {line})"
        super().__init__(f"{where}: {reason}")
        self.file, self.event, self.line, self.reason = file, event, line, reason


@dataclass(frozen=True)
class Event:
    """One timed action.  `value` by action: mode/state: the name; set/step: a
    {key: value} map; add_water: (tank, amount); log: "on" | "off"; fault:
    (kind, target, value, on); disturbance: (d1, d2), None for one left as it is;
    inputs_from: the log's path."""

    at: float
    action: str
    value: Any
    index: int  # 1-based position in the file
    line: int

    def where(self, file: str, reason: str) -> ScriptError:
        return ScriptError(file, reason, self.index, self.line)


@dataclass(frozen=True)
class Script:
    file: str
    events: tuple[Event, ...]  # in time order (stable: same time keeps file order)


def _error(name: str, message: str, line: int | None) -> ScriptError:
    return ScriptError(name, message, line=line)


def read_script(path: Path | str) -> Script:
    return parse_script(read_text(path, _error), name=str(path))


def parse_script(text: str, *, name: str = "<script>") -> Script:
    node, data = parse_yaml(text, name, _error)
    if data is None:
        return Script(name, ())
    import yaml

    if not isinstance(data, list) or not isinstance(node, yaml.SequenceNode):
        raise ScriptError(name, "a script is a list of events (- at: SECONDS, then one action)")
    events = [_event(name, item, i + 1, n.start_mark.line + 1)
              for i, (item, n) in enumerate(zip(data, node.value))]
    return Script(name, tuple(sorted(events, key=lambda e: e.at)))


def _event(file: str, item: Any, index: int, line: int) -> Event:
    def fail(reason: str) -> ScriptError:
        return ScriptError(file, reason, index, line)

    if not isinstance(item, dict):
        raise fail("an event is a mapping: at: SECONDS and one action")
    if "at" not in item:
        raise fail("no 'at' (seconds since the start)")
    at = item["at"]
    if not is_finite_number(at) or at < 0:
        raise fail(f"'at' must be a number of seconds >= 0, got {at!r}")
    actions = [k for k in item if k != "at"]
    unknown = [k for k in actions if k not in ACTIONS]
    if unknown:
        raise fail(f"unknown action {unknown[0]!r} (one of {', '.join(ACTIONS)})")
    if len(actions) != 1:
        raise fail(f"one action per event, got {len(actions)} ({', '.join(map(str, actions)) or 'none'})")
    action = actions[0]
    value = _check_value(action, item[action], fail)
    return Event(float(at), action, value, index, line)


def _check_value(action: str, value: Any, fail: Any) -> Any:
    if action == "mode":
        return _choice(value, MODES, "mode", fail)
    if action == "state":
        return _choice(value, STATES, "state", fail)
    if action == "log":
        # YAML reads a bare on/off as a boolean.
        text = {True: "on", False: "off"}.get(value, value) if isinstance(value, bool) else value
        return _choice(text, ("on", "off"), "log", fail)
    if action == "add_water":
        if not isinstance(value, dict) or set(value) != {"tank", "amount"}:
            raise fail("add_water needs {tank: 1..4, amount: <normalized level>}")
        tank, amount = value["tank"], value["amount"]
        if isinstance(tank, bool) or tank not in (1, 2, 3, 4):
            raise fail(f"add_water.tank must be 1..4, got {tank!r}")
        if not is_finite_number(amount):
            raise fail(f"add_water.amount must be a number, got {amount!r}")
        return (int(tank), float(amount))
    if action == "fault":
        return _fault(value, fail)
    if action == "disturbance":
        return _disturbance(value, fail)
    if action == "inputs_from":  # the log is read when the event comes (engine.inputs_from)
        if not isinstance(value, str) or not value.strip():
            raise fail(f"inputs_from needs the path of a log, got {value!r}")
        return value.strip()
    return _params(action, value, fail)


def _disturbance(value: Any, fail: Any) -> tuple[float | None, float | None]:
    """{d1: X, d2: Y} (either may be left out: unchanged), each 0..1 of full PWM."""
    if not isinstance(value, dict) or not value or not set(value) <= {"d1", "d2"}:
        raise fail("disturbance needs {d1: 0..1, d2: 0..1} (one may be left out)")
    for k, x in value.items():
        if not is_finite_number(x) or not 0.0 <= float(x) <= 1.0:
            raise fail(f"disturbance.{k} must be a number in 0..1 (a fraction of full PWM), got {x!r}")
    d1, d2 = value.get("d1"), value.get("d2")
    return (None if d1 is None else float(d1), None if d2 is None else float(d2))


def _fault(value: Any, fail: Any) -> tuple[str, int, float, bool]:
    """{kind, target, value (default 0), on (default on)}; the plant checks the rest
    (which tanks it has, the value's range) when the event is applied."""
    from quadtank_tui.core.faults import KINDS

    if isinstance(value, dict) and True in value and "on" not in value:  # YAML 1.1 reads the key on as true
        value = {("on" if k is True else k): v for k, v in value.items()}
    if not isinstance(value, dict) or not {"kind", "target"} <= set(value) or set(value) - {
            "kind", "target", "value", "on"}:
        raise fail("fault needs {kind: KIND, target: N, value: X, on: on|off} (value and on optional)")
    kind = value["kind"]
    if kind not in KINDS:
        raise fail(f"fault.kind must be one of {', '.join(KINDS)}, got {kind!r}")
    target = value["target"]
    if isinstance(target, bool) or not isinstance(target, int) or target < 1:
        raise fail(f"fault.target must be a whole number >= 1, got {target!r}")
    x = value.get("value", 0.0)
    if not is_finite_number(x):
        raise fail(f"fault.value must be a number, got {x!r}")
    on = value.get("on", True)
    on = {"on": True, "off": False}.get(on.strip().lower(), on) if isinstance(on, str) else on
    if not isinstance(on, bool):
        raise fail(f"fault.on must be on or off, got {value.get('on')!r}")
    return str(kind), int(target), float(x), on


def _choice(value: Any, choices: tuple[str, ...], what: str, fail: Any) -> str:
    for c in choices:
        if isinstance(value, str) and value.strip().lower() == c.lower():
            return c
    raise fail(f"{what} must be one of {', '.join(choices)}, got {value!r}")


def _params(action: str, value: Any, fail: Any) -> Mapping[str, Any]:
    if not isinstance(value, dict) or not value:
        raise fail(f"{action} needs a map of \"SECTION.Key\": value")
    out = {}
    for key, v in value.items():
        try:
            k = spec(str(key))
        except KeyError:
            raise fail(f"unknown parameter {key!r}") from None
        if action == "step" and k.kind is not Kind.NUMBER:
            raise fail(f"{key}: step adds to a number; this parameter is a {k.kind.value}")
        try:
            out[k.name] = k.coerce(v)
        except ParameterError as exc:
            raise fail(str(exc)) from None
    try:
        return check_names(out)  # a log name, log columns, plot types
    except ParameterError as exc:
        raise fail(str(exc)) from None
