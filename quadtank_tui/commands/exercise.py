"""`quadtank run --exercise FILE --par MINE.par [--record DIR]` (an attempt, headless)
and `quadtank exercise FILE` (the exercise window in the TUI); docs/exercises.md.

Bad input (an exercise file's mistake, a key the student may not change, a record
folder that holds another attempt) is one line on stderr and exit status 2."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from quadtank_tui.commands import UsageError, warn

if TYPE_CHECKING:
    from quadtank_tui.app.exercise import Attempt
    from quadtank_tui.files.exercise import Exercise


def add_run_options(p: argparse.ArgumentParser) -> None:
    """`quadtank run`'s options for an attempt at an exercise."""
    p.add_argument("--exercise", metavar="FILE",
                   help="run this exercise's experiment with --par's controllers, judge its requirements "
                   "(see docs/exercises.md); --duration and --log come from the exercise")
    p.add_argument("--record", metavar="DIR",
                   help="with --exercise: write the attempt's record folder (log, .par, controllers, "
                   "figures and verdicts, digests) for quadtank grade")


def read_checked(path: str) -> Exercise:
    """The exercise in `path`, or UsageError with its one line."""
    from quadtank_tui.files.exercise import ExerciseError, read_exercise

    try:
        return read_exercise(path)
    except ExerciseError as exc:
        raise UsageError(str(exc)) from None


def run_exercise(args: argparse.Namespace, clock: str, daq: object, daq_config: str | None) -> int:
    """`quadtank run --exercise`: the attempt, its verdicts printed, the record written."""
    from quadtank_tui.app.exercise import ExerciseRefused, run_attempt
    from quadtank_tui.files.script import read_script

    ex = read_checked(args.exercise)
    if args.par is None:
        raise UsageError("--exercise needs --par MINE.par: the parameters of your attempt")
    if args.duration is not None or args.log is not None:
        raise UsageError("--exercise sets the run's duration and log itself: leave out --duration and --log")
    record = Path(args.record) if args.record else None
    if record is not None and (record / "result.json").exists():
        raise UsageError(f"{record}: holds an attempt already (result.json); give a new folder")
    own = read_script(args.script) if args.script else None
    if own is not None and ex.experiment.script is not None:
        raise UsageError(f"{ex.id} has its own experiment: --script is for an exercise whose experiment "
                         "is your own run")
    try:
        attempt = run_attempt(ex, args.par, record=record, own_script=own, daq=daq,  # type: ignore[arg-type]
                              daq_config=daq_config, clock=clock, speed=args.speed,  # type: ignore[arg-type]
                              seed=args.seed)
    except ExerciseRefused as exc:
        raise UsageError(str(exc)) from None
    print(format_attempt(attempt))
    return attempt.status


def format_attempt(attempt: Attempt) -> str:
    """The summary of the run, then one line per requirement and the verdict."""
    lines = [attempt.summary, "", f"exercise   {attempt.exercise.id}: {attempt.exercise.title}"]
    width = max(len(v.name) for v in attempt.verdicts)
    for v in attempt.verdicts:
        state = "met" if v.met else "MISSED"
        detail = f"  ({v.detail})" if v.detail else ""
        lines.append(f"  {v.name:<{width}}  {v.figure_text():>12}  {v.requirement.limit_text():<12} {state}{detail}")
    met = sum(v.met for v in attempt.verdicts)
    lines.append(f"{'PASSED' if attempt.passed else 'NOT PASSED'}: {met} of {len(attempt.verdicts)} requirements met")
    if attempt.record is not None:
        lines.append(f"record     {attempt.record}")
    return "\n".join(lines)


def add_parser(sub: argparse._SubParsersAction, handler: Callable[[argparse.Namespace], int]) -> None:
    """`quadtank exercise FILE`; `handler` starts the TUI (cli.py's, which this layer
    may not import) once `prepare` has checked the files."""
    p = sub.add_parser(
        "exercise", help="open an exercise in the TUI: its text, its requirements live, the time left",
        description="The TUI on the simulator with an exercise's window open: the exercise's text, "
        "each requirement's state (pending, met, missed) with its figure as the run goes, the time "
        "left; the process image and trends as usual. The exercise's .par is loaded at the start.")
    p.add_argument("file", metavar="FILE", help="the exercise (YAML, docs/exercises.md)")
    p.add_argument("--par", metavar="MINE.par", dest="exercise_par",
                   help="start from your own .par (checked against what the exercise lets you change)")
    p.set_defaults(handler=handler)


def prepare(args: argparse.Namespace) -> None:
    """Check the exercise and the .par to start from, and set the TUI's options:
    a private session on that .par, and the exercise followed (args.exercise_tracker)."""
    import time

    from quadtank_tui.app.exercise import ExerciseRefused, LiveExercise, student_params

    ex = read_checked(args.file)
    if ex.runs_on == "rig" and not args.daq_global:
        raise UsageError(f"{ex.id} runs on the rig: quadtank --daq RIG.yaml exercise {args.file}")
    if ex.runs_on == "simulator" and args.daq_global:
        raise UsageError(f"{ex.id} runs on the simulator, not on a rig")
    par = args.exercise_par or ex.par
    try:
        _, warnings = student_params(ex, par)
    except ExerciseRefused as exc:
        raise UsageError(str(exc)) from None
    warn(warnings)
    args.tui_par = par
    args.no_session = True
    args.exercise_tracker = LiveExercise(ex, started=time.time())
