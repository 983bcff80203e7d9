"""The exercise use case: check a student's parameters, run the exercise's
experiment, measure every requirement and write the attempt's record.

`quadtank run --exercise`, the exercise window and `quadtank grade` (which runs an
attempt again) all come here, so the figures a student sees, the record's and the
grader's are computed by the same code.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from quadtank_tui.core.exercise import (
    KINDS, Requirement, RequirementError, Verdict, judge, live_state, signal_figure,
)
from quadtank_tui.core.exercise.figures import relative_error
from quadtank_tui.core.parameters import Parameters
from quadtank_tui.core.parameters.keys import iter_keys
from quadtank_tui.engine.backend import ProcessBackend
from quadtank_tui.engine.headless import HeadlessResult, finish_headless, prepare_headless
from quadtank_tui.engine.experiment import run_experiment
from quadtank_tui.engine.runner import ClockKind, load_parameters
from quadtank_tui.files.exercise import Exercise
from quadtank_tui.files.log_reader import LogData, read_log
from quadtank_tui.files.par import ParStore
from quadtank_tui.files.record import RecordFiles, digest, write_record
from quadtank_tui.files.script import Event, Script, read_script

#: What every exercise run logs, whatever a script says: the figures need them.
LOGGED = "t y1 y2 y3 y4 u1 u2 r1 r2"
#: Sections a student may always change: what is logged and plotted changes no figure.
FREE_SECTIONS = ("LOGGING", "PLOTS")
#: Two values of a key are the same when they agree to the .par's six decimals.
SAME = 5e-7


class ExerciseRefused(ValueError):
    """The student's parameters or run do not fit the exercise (a key not theirs
    to change, a controller type not allowed, the required event missing)."""


@dataclass(frozen=True)
class Attempt:
    """An attempt's figures: every requirement's verdict, the run's summary text and
    status (engine/headless), the log and the record folder (None: not kept)."""

    exercise: Exercise
    verdicts: tuple[Verdict, ...]
    summary: str
    status: int
    record: Path | None
    log: Path | None

    @property
    def passed(self) -> bool:
        return all(v.met for v in self.verdicts)


def exercise_params(ex: Exercise, params_dir: Path = Path("params")) -> Parameters:
    """The parameters the exercise sets (its `par`)."""
    return load_parameters(ex.par, ParStore(params_dir))[0]


def _same(a: Any, b: Any) -> bool:
    a, b = getattr(a, "value", a), getattr(b, "value", b)
    if isinstance(a, float) and isinstance(b, float):
        return abs(a - b) <= SAME * max(1.0, abs(a), abs(b))
    return bool(a == b)


def _shown(value: Any) -> str:
    value = getattr(value, "value", value)
    if isinstance(value, tuple):
        return " ".join(map(str, value))
    return f"{value:g}" if isinstance(value, float) else str(value)


def forbidden_changes(ex: Exercise, base: Parameters, mine: Parameters) -> list[str]:
    """The keys in which `mine` differs from the exercise's parameters without the
    exercise allowing it, as "KEY: exercise X, yours Y" (empty: all allowed)."""
    out = []
    for key in iter_keys():
        section = key.partition(".")[0]
        if section in FREE_SECTIONS or ex.may_change(key):
            continue
        if key == "CONTROL.Type" and ex.types:
            continue
        a, b = base.get(key), mine.get(key)
        if not _same(a, b):
            out.append(f"{key}: the exercise's {_shown(a)}, yours {_shown(b)}")
    typ = mine.get("CONTROL.Type")
    typ = getattr(typ, "value", typ)
    if ex.types and typ not in ex.types:
        out.insert(0, f"CONTROL.Type: {typ} is not allowed here (allowed: {', '.join(ex.types)})")
    return out


def student_params(ex: Exercise, par: str, params_dir: Path = Path("params")) -> tuple[Parameters, tuple[str, ...]]:
    """The student's parameters, checked against what the exercise lets them change."""
    mine, warnings = load_parameters(par, ParStore(params_dir))
    bad = forbidden_changes(ex, exercise_params(ex, params_dir), mine)
    if bad:
        more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
        raise ExerciseRefused(f"{par}: not yours to change in {ex.id}: {bad[0]}{more}")
    return mine, warnings


def attempt_script(ex: Exercise, own: Script | None) -> Script:
    """The script an attempt runs: the exercise's, or for "the student's own run"
    the student's; either way with LOGGED as the log's variables first (a script's
    own LOGGING.Variables is dropped: the figures need these columns)."""
    if ex.experiment.script is not None:
        script = read_script(ex.experiment.script)
    elif own is None:
        raise ExerciseRefused(f"{ex.id}: the experiment is your own run: give --script with its events "
                              f"(it must step {ex.experiment.own_run.key if ex.experiment.own_run else ''} "
                              "in Automatic)")
    else:
        script = own
    events = []
    for e in script.events:
        if e.action == "set" and "LOGGING.Variables" in e.value:
            rest = {k: v for k, v in e.value.items() if k != "LOGGING.Variables"}
            if not rest:
                continue
            e = dataclasses.replace(e, value=rest)
        events.append(e)
    first = Event(0.0, "set", {"LOGGING.Variables": tuple(LOGGED.split())}, 0, 0)
    return Script(script.file, (first, *events))


def check_own_run(ex: Exercise, cols: Mapping[str, np.ndarray], automatic_since: float | None) -> str | None:
    """Why the student's own run lacks the required event (None: it has it): a
    step of the reference by the asked amount (within 5 %) in Automatic."""
    own = ex.experiment.own_run
    if own is None:
        return None
    r, t = np.asarray(cols[f"r{own.loop}"]), np.asarray(cols["t"])
    jumps = np.diff(r)
    hit = np.nonzero(np.abs(jumps - own.delta) <= 0.05 * abs(own.delta))[0]
    if hit.size == 0:
        return f"the run has no step of {own.delta:+g} on r{own.loop} ({own.key})"
    if automatic_since is None or t[hit[-1] + 1] < automatic_since - 1e-9:
        return f"the step of r{own.loop} at {t[hit[-1] + 1]:g} s was not in Automatic"
    return None


def own_run_verdict(ex: Exercise, cols: Mapping[str, np.ndarray], automatic_since: Any) -> Verdict:
    """The student's own run holds the required event (figure 1) or not (0, and why)."""
    since = float(automatic_since) if isinstance(automatic_since, (int, float)) else None
    missing = check_own_run(ex, cols, since)
    return judge(Requirement("required_event", 1.0), 1.0 if missing is None else 0.0, missing or "")


def evaluate(ex: Exercise, params: Parameters, cols: Mapping[str, np.ndarray], h: float, *,
             seconds: float | None = None, finished: bool = True) -> tuple[Verdict, ...]:
    """Every requirement's verdict on a run's columns (the log's names), the
    parameters in force (the design kinds) and the attempt's wall seconds."""
    model: dict[str, Any] | None = None
    out = []
    for req in ex.requirements:
        what = KINDS[req.kind].what
        try:
            if what in ("step", "log"):
                figure, detail = signal_figure(req, cols, h)
            elif what == "design":
                figure, detail = design_figure(ex, params, req)
            elif what == "model":
                if model is None:
                    model = identified(ex, params, cols, h)
                figure, detail = model_figure(req, model)
            else:
                figure, detail = seconds, ("" if seconds is not None else "no end time")
        except RequirementError as exc:
            figure, detail = None, str(exc)
        out.append(judge(req, figure, detail))
    return tuple(out)


def design_figure(ex: Exercise, params: Parameters, req: Requirement) -> tuple[float | None, str]:
    """Ms or a margin of the student's loop `req.loop` sampled at the parameters'
    TSamp, on the linearization of the exercise's plant (core.design)."""
    from quadtank_tui.core.design.apply import in_force
    from quadtank_tui.core.design.mimo import model_in_use
    from quadtank_tui.core.design.sampled_eval import evaluate_sampled

    loop = int(req.loop or 1)
    G = model_in_use(exercise_params(ex))
    c = in_force(params, loop)
    ev = evaluate_sampled(c, G[loop - 1][loop - 1], params.tsamp, u0=None).evaluation
    where = f"K {c.Kc:.4g}, Ti {c.Ti:.4g} on G{loop}{loop} at h {params.tsamp:g} s"
    if not ev.stable:
        return None, f"the loop is unstable ({where})"
    value = {"ms": ev.Ms, "phase_margin": ev.phase_margin_deg, "gain_margin": ev.gain_margin}[req.kind]
    return float(value), where


def identified(ex: Exercise, params: Parameters, cols: Mapping[str, np.ndarray], h: float) -> dict[str, Any]:
    """The model the exercise's identification finds in the log, and the physical
    linearization at the log's first row to compare it with."""
    from quadtank_tui.core.identify.compare import compare
    from quadtank_tui.core.identify.experiment import Options, Record, identify

    opts = Options(method=ex.identify.method, order=ex.identify.order, zeros=ex.identify.zeros)
    try:
        ident = identify([Record("run.log", h, dict(cols))], opts)
    except ValueError as exc:
        raise RequirementError(f"the identification failed: {exc}") from None
    plant = exercise_params(ex).quadtank_constants()
    cmp = compare(ident.operating_point, plant, ident.system.static_gains, ident.inputs, ident.outputs, (3.0, 3.0))
    return {"zeros": ident.system.zeros, "gains": np.asarray(ident.system.static_gains),
            "physical_zeros": cmp.physical.zeros, "physical_gains": np.asarray(cmp.physical.static_gains),
            "outputs": ident.outputs, "inputs": ident.inputs}


def model_figure(req: Requirement, model: Mapping[str, Any]) -> tuple[float | None, str]:
    """The relative error of the identified zero nearest the origin (model_zero), or
    of a static gain (model_gain), against the physical linearization's."""
    if req.kind == "model_zero":
        zs, ps = list(model["zeros"]), list(model["physical_zeros"])
        if not zs or not ps:
            return None, "no finite transmission zero in the " + ("model" if not zs else "physical model")
        z, p = min(zs, key=abs), min(ps, key=abs)
        err = abs(z - p) / abs(p)
        return float(err), f"zero {_c(z)} 1/s against the physical {_c(p)}"
    i, j = int(str(req.element)[0]) - 1, int(str(req.element)[1]) - 1
    g, gp = model["gains"], model["physical_gains"]
    if i >= g.shape[0] or j >= g.shape[1]:
        return None, f"the model has no element G{req.element}"
    return relative_error(float(g[i, j]), float(gp[i, j])), \
        f"gain {g[i, j]:.4g} against the physical {gp[i, j]:.4g}"


def _c(z: complex) -> str:
    return f"{z.real:+.4f}" if abs(z.imag) < 1e-12 else f"{z.real:+.4f}{z.imag:+.4f}j"


def log_columns(log: LogData) -> dict[str, np.ndarray]:
    """A log's columns with `t` (rows x TSamp when not logged)."""
    cols = log.columns()
    if "t" not in cols:
        cols["t"] = np.arange(log.rows) * float(log.tsamp or 1.0)
    return cols


def controllers(ex: Exercise, params: Parameters) -> dict[str, Any]:
    """The controllers in force as the record keeps them: every controller key, and
    for a decentralized PID its loops' figures on the exercise's plant (Ms, margins)
    and the design preview on the nonlinear simulator (core.design.preview)."""
    out: dict[str, Any] = {"values": {}}
    for key in iter_keys():
        if key.startswith(("CONTROL", "STATE FEEDBACK", "MPC")):
            v = params.get(key)
            v = getattr(v, "value", v)
            out["values"][key] = list(v) if isinstance(v, tuple) else v
    if params.get("CONTROL.Type") != "PID" and getattr(params.get("CONTROL.Type"), "value", "") != "PID":
        return out
    try:
        from quadtank_tui.core.design.apply import in_force
        from quadtank_tui.core.design.mimo import model_in_use
        from quadtank_tui.app.design import preview_plan
        from quadtank_tui.core.design.sampled_eval import evaluate_sampled

        G = model_in_use(exercise_params(ex))
        pair = [in_force(params, i) for i in (1, 2)]
        evs = [evaluate_sampled(c, G[i][i], params.tsamp, u0=None).evaluation for i, c in enumerate(pair)]
        out["loops"] = [{"loop": i + 1, "K": c.Kc, "Ti": c.Ti if math.isfinite(c.Ti) else None, "Td": c.Td,
                         **ev.to_dict()} for i, (c, ev) in enumerate(zip(pair, evs))]
        pv = preview_plan(params, pair, G, params.tsamp).run()  # each step until it settles
        out["preview"] = pv.to_dict()
    except (ValueError, ArithmeticError) as exc:  # a design error, a plant the 2x2 check cannot take
        out["design_error"] = str(exc)
    return out


def in_log_time(t: float | None, log_start: float) -> float | None:
    """A process time as the log's `t` column counts it (from its LogOn)."""
    return None if t is None else t - log_start


def plant_identity(params: Parameters, daq: ProcessBackend | None, daq_config: str | None) -> dict[str, Any]:
    """Where the attempt ran: the simulator (its plant's title), or the rig as far
    as this program can tell it: the DAQ file (path and sha256), the device's
    address and what the backend reports (`identity`, when the backend has one)."""
    if daq is None:
        return {"kind": "simulator", "model": params.process_plant().title}
    out: dict[str, Any] = {"kind": "rig", "backend": type(daq).__name__}
    if daq_config is not None:
        path = Path(daq_config)
        out["daq_file"] = str(path.resolve())
        try:
            out["daq_sha256"] = digest(path.read_bytes())
        except OSError:
            out["daq_sha256"] = None
    config = getattr(daq, "config", None)
    for key in ("host", "port", "device_id", "port_name", "device"):
        value = getattr(config, key, None)
        if isinstance(value, (str, int, float)) and not isinstance(value, bool):
            out[key] = value
    out["device_identity"], out["identity_mismatches"] = device_identity(daq)
    return out


def device_identity(daq: ProcessBackend) -> tuple[dict[str, Any] | None, list[str]]:
    """What the rig says of itself (its identity block, daq/identity.py: pump
    amplifiers, sensor scales, pump range) and where the DAQ file in force
    disagrees with it; (None, []) from a device that serves none (a real LabJack)
    or a link that cannot read it now."""
    from dataclasses import asdict

    from quadtank_tui.daq.modbus import BackendError

    read = getattr(daq, "rig_identity", None)
    differ = getattr(daq, "identity_mismatches", None)
    if not callable(read):
        return None, []
    try:
        identity = read()
        pumps, sensors = differ() if callable(differ) and identity is not None else ([], [])
    except BackendError:
        return None, []
    if identity is None:
        return None, []
    return {k: list(v) for k, v in asdict(identity).items()}, [*pumps, *sensors]


def run_attempt(ex: Exercise, par: str, *, record: Path | None = None, own_script: Script | None = None,
                daq: ProcessBackend | None = None, daq_config: str | None = None, clock: ClockKind = "manual",
                speed: float | None = None, seed: int | None = None, user: str | None = None,
                params_dir: Path = Path("params")) -> Attempt:
    """Run the exercise's experiment with the student's `par` (checked first), judge
    every requirement, and with `record` write the record folder (files/record.py).
    ExerciseRefused for a .par or a run that does not fit the exercise."""
    if daq is None and ex.runs_on == "rig":
        raise ExerciseRefused(f"{ex.id} runs on the rig: give --daq with the rig's DAQ file")
    if daq is not None and ex.runs_on == "simulator":
        raise ExerciseRefused(f"{ex.id} runs on the simulator, not on a rig")
    params, _ = student_params(ex, par, params_dir)
    script = attempt_script(ex, own_script)
    with tempfile.TemporaryDirectory(prefix="quadtank-exercise-") as tmp:
        out = (record if record is not None else Path(tmp)) / "run.log"
        if record is not None:
            record.mkdir(parents=True, exist_ok=True)
        started = datetime.now(timezone.utc)
        run = prepare_headless(par=par, script=script, duration=ex.experiment.duration, out=out, seed=seed,
                               clock=clock, speed=speed, params_dir=params_dir, daq=daq)
        try:
            run_experiment(run.engine, script, ex.experiment.duration)
            result: HeadlessResult = finish_headless(run)
            automatic_since = in_log_time(run.engine.automatic_since, run.engine.log_started_at)
        finally:
            run.engine.stop()
        ended = datetime.now(timezone.utc)
        if result.log is None:
            raise ExerciseRefused(f"{ex.id}: the run wrote no log: {result.text.splitlines()[-1]}")
        log = read_log(result.log)
        cols = log_columns(log)
        verdicts = evaluate(ex, params, cols, params.tsamp, seconds=(ended - started).total_seconds())
        if ex.experiment.own_run is not None:
            verdicts = (*verdicts, own_run_verdict(ex, cols, automatic_since))
        saved = None
        if record is not None:
            saved = write_record(RecordFiles(
                folder=record, exercise=ex.path, params=params, script=script, log=result.log,
                controllers=controllers(ex, params), verdicts=verdicts, exercise_id=ex.id,
                exercise_digest=ex.digest, plant=plant_identity(params, daq, daq_config),
                started=started, ended=ended, user=user, automatic_since=automatic_since,
                summary=result.text, seed=seed,
                experiment="script" if ex.experiment.script is not None else "own run"))
        return Attempt(ex, verdicts, result.text, result.status, saved, result.log if record else None)


#: The engine's history names its references ref1, ref2; a log r1, r2.
HISTORY_NAMES = {"ref1": "r1", "ref2": "r2"}


def watch_time(ex: Exercise) -> float:
    """Seconds an attempt is watched in Automatic: the experiment's duration after its
    script's first switch to Automatic (the whole duration for the student's own run)."""
    if ex.experiment.script is None:
        return ex.experiment.duration
    switch = [e.at for e in read_script(ex.experiment.script).events
              if e.action == "mode" and e.value == "Automatic"]
    return ex.experiment.duration - (min(switch) if switch else 0.0)


@dataclass(frozen=True)
class LiveRow:
    """One requirement as the exercise window shows it now."""

    name: str
    limit: str
    figure: str
    state: str  # "pending", "met" or "missed"
    detail: str


@dataclass(frozen=True)
class LiveState:
    rows: tuple[LiveRow, ...]
    time_left: float | None  # s of the exercise's time limit left (None: no limit)
    watched: float           # s of the attempt watched so far (in Automatic)
    watch: float             # s it is watched for
    finished: bool

    def summary(self) -> str:
        met = sum(r.state == "met" for r in self.rows)
        if not self.finished:
            return f"attempt running: {self.watched:.0f} of {self.watch:.0f} s watched, {met} of {len(self.rows)} met so far"
        verdict = "PASSED" if met == len(self.rows) else "NOT PASSED"
        return f"attempt finished: {met} of {len(self.rows)} requirements met: {verdict}"


class LiveExercise:
    """An exercise followed in the TUI as the student works: when the loops went
    into Automatic (the attempt's start), the figures of the history since then, the
    time left.  The model kinds (an identification: seconds of CPU) are judged once
    the attempt is finished; the design kinds whenever the controllers change."""

    def __init__(self, ex: Exercise, *, started: float, params_dir: Path = Path("params")) -> None:
        self.exercise = ex
        self.started = started  # wall clock (s) the exercise was opened
        self.watch = watch_time(ex)
        self.params_dir = params_dir
        self.automatic_since: float | None = None
        self._final: LiveState | None = None
        self._design: dict[tuple[Any, ...], tuple[float | None, str]] = {}

    def note(self, automatic_since: float | None) -> None:
        """Each snapshot's switch to Automatic (engine Snapshot.automatic_since): the
        attempt starts there (again at each new switch); Manual ends it unfinished."""
        if automatic_since != self.automatic_since:
            self.automatic_since, self._final = automatic_since, None

    def state(self, history: Mapping[str, np.ndarray], params: Parameters, now: float) -> LiveState:
        """The requirements' states on the history given (the engine's, names as its
        SIGNALS) at wall time `now`."""
        ex = self.exercise
        left = None if ex.time_limit is None else ex.time_limit - (now - self.started)
        if self._final is not None:
            return dataclasses.replace(self._final, time_left=left)
        since = self.automatic_since
        t = np.asarray(history.get("t", np.zeros(0)))
        # the newest sample is at t[-1]: it covers the sampling period after it
        watched = 0.0 if since is None or t.size == 0 else float(t[-1] - since + params.tsamp)
        finished = since is not None and watched >= self.watch - 1e-9
        rows = []
        keep = t >= since - 1e-9 if since is not None else np.zeros(t.size, dtype=bool)
        cols = {HISTORY_NAMES.get(k, k): np.asarray(v)[keep] for k, v in history.items()}
        if since is not None and cols["t"].size:
            cols["t"] = cols["t"] - cols["t"][0]
        for req in ex.requirements:
            what = KINDS[req.kind].what
            figure: float | None = None
            detail = ""
            if what == "design":
                figure, detail = self._design_figure(params, req)
            elif what == "attempt":
                figure = now - self.started
            elif what == "model":
                detail = "identified when the attempt is finished" if not finished else ""
                if finished:
                    try:
                        figure, detail = model_figure(req, identified(ex, params, cols, params.tsamp))
                    except RequirementError as exc:
                        detail = str(exc)
            elif since is None or cols["t"].size < 2:
                detail = "waits for Automatic"
            else:
                try:
                    figure, detail = signal_figure(req, cols, params.tsamp)
                except RequirementError as exc:
                    detail = str(exc)
            state = live_state(req, figure, finished or what == "design")
            v = judge(req, figure, detail)
            rows.append(LiveRow(req.name, req.limit_text(), v.figure_text(), state, detail))
        out = LiveState(tuple(rows), left, watched, self.watch, finished)
        if finished:
            self._final = out
        return out

    def _design_figure(self, params: Parameters, req: Requirement) -> tuple[float | None, str]:
        key = (req.name, *(getattr(params.get(k), "value", params.get(k)) for k in iter_keys()
                           if k.startswith("CONTROLLER") or k == "SAMPLING TIME.TSamp"))
        if key not in self._design:
            try:
                self._design[key] = design_figure(self.exercise, params, req)
            except (ValueError, ArithmeticError) as exc:
                self._design[key] = (None, str(exc))
        return self._design[key]

    def record(self, history: Mapping[str, np.ndarray], params: Parameters, folder: Path, *,
               now: datetime, rig: bool, backend: str) -> Path:
        """Write the record of the attempt by hand (the history since the switch to
        Automatic as run.log, the parameters in force), its figures judged on that
        log as `quadtank grade` will: an "interactive" record, which the grader
        reads (digests, figures from the log) but cannot run again."""
        from quadtank_tui.files.log_writer import format_header, format_row

        since = self.automatic_since
        if since is None:
            raise ExerciseRefused("no attempt to record: the loops are not in Automatic")
        t = np.asarray(history["t"])
        keep = t >= since - 1e-9
        names = LOGGED.split()
        cols = {HISTORY_NAMES.get(k, k): np.asarray(v)[keep] for k, v in history.items()}
        cols["t"] = cols["t"] - since
        folder.mkdir(parents=True, exist_ok=False)
        log = folder / "run.log"
        text = format_header(names, params.tsamp, now.replace(tzinfo=None))
        text += "".join(format_row([float(cols[n][i]) for n in names]) for i in range(int(keep.sum())))
        log.write_text(text, encoding="ascii")
        logged = log_columns(read_log(log))
        started = datetime.fromtimestamp(self.started, timezone.utc)
        verdicts = evaluate(self.exercise, params, logged, params.tsamp, seconds=now.timestamp() - self.started)
        if self.exercise.experiment.own_run is not None:
            verdicts = (*verdicts, own_run_verdict(self.exercise, logged, 0.0))
        plant: dict[str, Any] = {"kind": "rig", "backend": backend, "device_identity": None} if rig else \
            {"kind": "simulator", "model": params.process_plant().title}
        return write_record(RecordFiles(
            folder=folder, exercise=self.exercise.path, params=params, script=None, log=log,
            controllers=controllers(self.exercise, params), verdicts=verdicts, exercise_id=self.exercise.id,
            exercise_digest=self.exercise.digest, plant=plant, started=started, ended=now,
            automatic_since=0.0, summary="an attempt by hand in the TUI", experiment="interactive"))
