"""The grade use case: re-derive every figure of an attempt's record that can be
re-derived, and say which were reproduced, which could only be read, and which do
not match.

On the simulator an attempt is deterministic: the recorded `.par` is run again on
the exercise's experiment (the teacher's exercise file, never the record's copy)
and the new log must equal the recorded one byte for byte; the requirements are
then judged on the new log.  On a rig the log cannot be had again: it is checked
against the record's digests and the rig's identity, and the figures are
recomputed from it ("read").  An edited file is named: its sha256 differs from the
record's, or the run does not come out as recorded.
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence, Union

import numpy as np

from quadtank_tui.app.exercise import (
    ExerciseRefused, in_log_time, attempt_script, evaluate, forbidden_changes, exercise_params, log_columns,
    own_run_verdict,
)
from quadtank_tui.core.exercise import Verdict
from quadtank_tui.core.exercise.figures import last_step_index
from quadtank_tui.engine.experiment import run_experiment
from quadtank_tui.engine.headless import finish_headless, prepare_headless
from quadtank_tui.engine.runner import load_parameters
from quadtank_tui.files.exercise import NOT_A_MAPPING, Exercise, ExerciseError, read_exercise
from quadtank_tui.files.log_reader import parse_log
from quadtank_tui.files.par import ParStore, parse_par
from quadtank_tui.files.record import FILES, RecordError, digest, read_file, read_result
from quadtank_tui.files.script import ScriptError, parse_script

Reproduced = Union[bool, str]  # True, False or "read"
#: A recorded figure and a re-derived one agree to this relative difference
#: (the record's JSON keeps a float's every digit: they are equal on a reproduction).
AGREE = 1e-9


@dataclass
class GradedRequirement:
    name: str
    figure: float | None
    limit: float
    met: bool
    reproduced: Reproduced
    recorded_figure: float | None = None
    recorded_met: bool | None = None
    detail: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "figure": _finite(self.figure), "limit": self.limit, "met": self.met,
                "reproduced": self.reproduced, "recorded_figure": _finite(self.recorded_figure),
                "recorded_met": self.recorded_met, "detail": self.detail}


@dataclass
class Graded:
    """One attempt as graded.  `notes` name what does not match (an edited file)."""

    folder: Path
    user: str
    exercise: str
    started: str
    plant: str
    requirements: list[GradedRequirement]
    passed: bool
    reproduced: Reproduced
    notes: list[str] = field(default_factory=list)
    #: the stepped loop's response after its step (s from the step, level), for the class figure
    curve: tuple[np.ndarray, np.ndarray] | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"record": str(self.folder), "user": self.user, "exercise": self.exercise,
                "started": self.started, "plant": self.plant,
                "requirements": [r.to_dict() for r in self.requirements], "passed": self.passed,
                "reproduced": self.reproduced, "notes": self.notes}


def _finite(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else x


def load_exercises(paths: Iterable[Path]) -> dict[str, Exercise]:
    """The teacher's exercises by id, from files and folders of `*.yaml` exercise
    files (a folder's other YAML files, its scripts, are skipped)."""
    out: dict[str, Exercise] = {}
    for path in paths:
        files = sorted(path.glob("*.yaml")) if path.is_dir() else [path]
        for f in files:
            try:
                ex = read_exercise(f)
            except ExerciseError as exc:
                if path.is_dir() and exc.reason.startswith(NOT_A_MAPPING):
                    continue  # a script (a list of events) next to the exercises
                raise  # a teacher's mistake is said, not skipped
            out[ex.id] = ex
    return out


def grade_record(folder: Path, exercises: Mapping[str, Exercise], *, daq_digests: Sequence[str] = (),
                 params_dir: Path = Path("params")) -> Graded:
    """Grade one record folder; RecordError if it cannot be read at all."""
    result = read_result(folder)
    notes: list[str] = []
    data: dict[str, bytes] = {}
    edited: set[str] = set()
    recorded_digests = result["sha256"]
    for name in FILES:
        try:
            data[name] = read_file(folder, name)
        except RecordError as exc:
            notes.append(str(exc))
            edited.add(name)
            continue
        if digest(data[name]) != recorded_digests.get(name):
            edited.add(name)
            notes.append(f"{name} edited: its sha256 is not the one result.json records")
    ex_id = str(result["exercise"].get("id", "?"))
    user = str(result["user"].get("name", "?"))
    owner = _owner(folder / "result.json")
    uid = result["user"].get("uid")
    if owner is not None and owner != uid:
        notes.append(f"result.json belongs to uid {owner}, not to the recorded user's uid {uid!r} "
                     "(copied, or written by another user)")
    plant = result["plant"]
    kind = plant.get("kind")
    ex = exercises.get(ex_id)
    if ex is None:
        notes.append(f"exercise {ex_id!r} is not among the exercises given: its figures are only read")
    elif "exercise.yaml" in data and digest(data["exercise.yaml"]) != ex.digest:
        notes.append(f"exercise.yaml is not the teacher's {ex.path.name} (edited, or another version): "
                     "graded against the teacher's")
    wrong_plant = ex is not None and ((ex.runs_on == "rig" and kind != "rig") or
                                      (ex.runs_on == "simulator" and kind != "simulator"))
    if wrong_plant and ex is not None:
        notes.append(f"{ex.id} runs on the {ex.runs_on}; this attempt ran on the {kind}")
    recorded = {str(r.get("name")): r for r in result["requirements"] if isinstance(r, dict)}
    seconds = _seconds(result)
    log_bytes = data.get("run.log")
    verdicts: tuple[Verdict, ...] | None = None
    log_reproduced: Reproduced = "read"
    cols = None
    interactive = result.get("experiment") == "interactive"
    if interactive:
        notes.append("an attempt by hand in the TUI: its figures are read from its log, not run again")
    if ex is not None and kind == "simulator" and "student.par" in data and not interactive:
        try:
            verdicts, cols, same = _rerun(ex, data, result, seconds, notes, params_dir)
        except (ValueError, OSError) as exc:
            notes.append(f"cannot run it again: {exc}")
        else:
            log_reproduced = same
            if not same:
                if "student.par" in edited:
                    notes.append("student.par edited: the run of the recorded .par is not the recorded log")
                elif "run.log" in edited:
                    pass  # named already: its digest
                else:
                    notes.append("run.log does not match the run of the recorded .par and script "
                                 "(the record was rewritten, or by another program version)")
    elif kind == "rig":
        _check_rig(plant, daq_digests, notes)
    if verdicts is None and ex is not None and log_bytes is not None:
        try:  # the figures from the recorded log: read, not reproduced
            log = parse_log(log_bytes, name=str(folder / "run.log"))
            cols = log_columns(log)
            params = parse_par(data.get("student.par", b""), base=exercise_params(ex, params_dir)).params
            verdicts = evaluate(ex, params, cols, params.tsamp, seconds=seconds)
            if ex.experiment.own_run is not None:
                verdicts = (*verdicts, own_run_verdict(ex, cols, result.get("automatic_since")))
        except (ValueError, OSError) as exc:
            notes.append(f"run.log cannot be read: {exc}")
    graded = _compare(verdicts, recorded, log_reproduced, notes)
    simulated_ok = log_reproduced is True
    bad = any(r.reproduced is False for r in graded) or (kind == "rig" and bool(edited))
    if kind != "simulator" and kind != "rig":
        notes.append(f"result.json names no plant the grader knows ({kind!r})")
    reproduced: Reproduced = False if bad or log_reproduced is False else (True if simulated_ok else "read")
    allowed = not any(n.startswith("student.par changes") for n in notes)
    passed = bool(graded) and all(r.met for r in graded) and reproduced is not False and allowed \
        and not wrong_plant
    curve = _curve(ex, cols) if ex is not None and cols is not None else None
    return Graded(folder, user, ex_id, str(result.get("started", "")), str(kind), graded, passed, reproduced,
                  notes, curve)


def _owner(path: Path) -> int | None:
    """The OS's word on whose file it is (its owner's uid), None if it cannot say."""
    try:
        return os.lstat(path).st_uid
    except OSError:
        return None


def _seconds(result: Mapping[str, Any]) -> float | None:
    from datetime import datetime

    try:
        return (datetime.fromisoformat(str(result["ended"])) - datetime.fromisoformat(str(result["started"]))
                ).total_seconds()
    except (KeyError, ValueError):
        return None


def _rerun(ex: Exercise, data: Mapping[str, bytes], result: Mapping[str, Any], seconds: float | None,
           notes: list[str], params_dir: Path) -> tuple[tuple[Verdict, ...], dict[str, np.ndarray], bool]:
    """The attempt again on the simulator: its verdicts, columns, and whether the
    log came out byte for byte as recorded."""
    seed = result.get("seed")
    seed = seed if isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0 else None
    with tempfile.TemporaryDirectory(prefix="quadtank-grade-") as tmp:
        par = Path(tmp) / "student.par"
        par.write_bytes(data["student.par"])
        mine, _ = load_parameters(str(par), ParStore(params_dir))
        bad = forbidden_changes(ex, exercise_params(ex, params_dir), mine)
        if bad:
            notes.append(f"student.par changes what the exercise does not allow: {bad[0]}")
        own = None
        if ex.experiment.own_run is not None:
            try:
                own = parse_script(data.get("script.yaml", b"").decode("utf-8", "replace"), name="script.yaml")
            except ScriptError as exc:
                raise ValueError(str(exc)) from None
        script = attempt_script(ex, own)
        run = prepare_headless(par=str(par), script=script, duration=ex.experiment.duration,
                               out=Path(tmp) / "run.log", seed=seed, params_dir=params_dir)
        try:
            run_experiment(run.engine, script, ex.experiment.duration)
            res = finish_headless(run)
            automatic_since = in_log_time(run.engine.automatic_since, run.engine.log_started_at)
        finally:
            run.engine.stop()
        if res.log is None:
            raise ValueError("the run wrote no log")
        new = res.log.read_bytes()
        cols = log_columns(parse_log(new, name="run.log"))
        verdicts = evaluate(ex, mine, cols, mine.tsamp, seconds=seconds)
        if ex.experiment.own_run is not None:
            verdicts = (*verdicts, own_run_verdict(ex, cols, automatic_since))
        return verdicts, cols, new == data.get("run.log")


def _check_rig(plant: Mapping[str, Any], daq_digests: Sequence[str], notes: list[str]) -> None:
    if not plant.get("daq_sha256"):
        notes.append("the record names no DAQ file of the rig")
    elif daq_digests and plant["daq_sha256"] not in daq_digests:
        notes.append("the rig's DAQ file is not the one given (--daq): another rig, or its file was changed")
    if plant.get("device_identity") is None:
        notes.append("the rig gave no identity of its own (only its DAQ file and address are recorded)")
    elif plant.get("identity_mismatches"):
        notes.append("the rig's own identity disagreed with its DAQ file: " + ", ".join(map(str, plant["identity_mismatches"])))


def _close(a: float | None, b: Any) -> bool:
    if a is None or not isinstance(b, (int, float)) or isinstance(b, bool):
        return a is None and b is None
    if not (math.isfinite(a) and math.isfinite(float(b))):
        return a == b
    return abs(a - float(b)) <= AGREE * max(1.0, abs(a), abs(float(b)))


def _compare(verdicts: tuple[Verdict, ...] | None, recorded: Mapping[str, Mapping[str, Any]],
             log_reproduced: Reproduced, notes: list[str]) -> list[GradedRequirement]:
    out: list[GradedRequirement] = []
    if verdicts is None:  # nothing to re-derive with: the record's word, read
        for name, r in recorded.items():
            figure = r.get("figure")
            out.append(GradedRequirement(name, figure if isinstance(figure, (int, float)) else None,
                                         float(r.get("limit") or 0.0), bool(r.get("met")), "read",
                                         figure, bool(r.get("met")), str(r.get("detail", ""))))
        return out
    mismatched = []
    for v in verdicts:
        rec = recorded.get(v.name)
        rec_fig = rec.get("figure") if rec else None
        rec_met = bool(rec.get("met")) if rec else None
        same = rec is not None and _close(v.figure, rec_fig) and rec_met == v.met
        if v.requirement.kind == "time_limit":
            rep: Reproduced = "read" if same else False
        elif not same:
            rep = False
            mismatched.append(v.name)
        else:
            rep = log_reproduced if log_reproduced is not False else True
        out.append(GradedRequirement(v.name, v.figure, v.requirement.limit, v.met, rep,
                                     rec_fig if isinstance(rec_fig, (int, float)) else None, rec_met, v.detail))
    extra = [n for n in recorded if n not in {v.name for v in verdicts}]
    if mismatched:
        source = "the log gives" if log_reproduced is not False else "the run of the recorded .par gives"
        notes.append(f"result.json edited: {', '.join(mismatched)} not as {source} "
                     f"({'; '.join(_mismatch(v, recorded) for v in verdicts if v.name in mismatched)})")
    if extra:
        notes.append(f"result.json has requirements the exercise does not: {', '.join(extra)}")
    return out


def _mismatch(v: Verdict, recorded: Mapping[str, Mapping[str, Any]]) -> str:
    r = recorded.get(v.name)
    if r is None:
        return f"{v.name} missing"
    return f"{v.name} recorded {r.get('figure')!r} {'met' if r.get('met') else 'missed'}, is {v.figure_text()} " \
           f"{'met' if v.met else 'missed'}"


def _curve(ex: Exercise, cols: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray] | None:
    """The stepped loop's level after its step, against seconds since the step."""
    loop = next((r.loop for r in ex.requirements if r.loop is not None), 1)
    if ex.experiment.own_run is not None:
        loop = ex.experiment.own_run.loop
    r, y, t = cols.get(f"r{loop}"), cols.get(f"y{loop}"), cols.get("t")
    if r is None or y is None or t is None:
        return None
    k = last_step_index(r)
    if k is None:
        return None
    return np.asarray(t[k - 1:] - t[k]), np.asarray(y[k - 1:])


def reference_curve(ex: Exercise, params_dir: Path = Path("params")) -> tuple[np.ndarray, np.ndarray] | None:
    """The reference solution's response (run now), for the class figure."""
    if ex.reference is None or ex.experiment.script is None:
        return None
    from quadtank_tui.app.exercise import run_attempt

    with tempfile.TemporaryDirectory(prefix="quadtank-reference-") as tmp:
        try:
            attempt = run_attempt(ex, str(ex.reference), record=Path(tmp) / "ref", params_dir=params_dir)
        except (ExerciseRefused, ValueError, OSError):
            return None
        if attempt.log is None:
            return None
        from quadtank_tui.files.log_reader import read_log

        return _curve(ex, log_columns(read_log(attempt.log)))


def best_attempts(graded: Sequence[Graded]) -> list[Graded]:
    """Per student and exercise the best attempt: passed and reproduced first, then
    the most requirements met, then the latest."""
    best: dict[tuple[str, str], Graded] = {}
    for g in graded:
        key = (g.user, g.exercise)
        if key not in best or _rank(g) > _rank(best[key]):
            best[key] = g
    return sorted(best.values(), key=lambda g: (g.exercise, g.user))


def _rank(g: Graded) -> tuple[bool, bool, int, str]:
    return (g.passed, g.reproduced is not False, sum(r.met for r in g.requirements), g.started)
