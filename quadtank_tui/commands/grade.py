"""`quadtank grade RECORD... [--json] [--csv FILE] [--figures DIR]`: a class's
attempts in one table (app/grade.py re-derives the figures; docs/exercises.md)."""

from __future__ import annotations

import argparse
import csv
import io
import json
from pathlib import Path
from typing import TYPE_CHECKING, Mapping, Sequence

from quadtank_tui.commands import UsageError

if TYPE_CHECKING:
    from quadtank_tui.app.grade import Graded
    from quadtank_tui.files.exercise import Exercise

#: Where the teacher's exercises are found unless --exercises says.
DEFAULT_EXERCISES = Path("params/exercises")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "grade", help="grade exercise records: re-derive every figure, flag edited files, one table",
        description="Grade the records of exercise attempts (quadtank run --exercise ... --record DIR): "
        "a simulator attempt is run again and must give the recorded log byte for byte; a rig's log is "
        "checked against the record's digests. One row per attempt, then the best attempt per student.")
    p.add_argument("records", nargs="+", metavar="RECORD",
                   help="record folders, or folders of record folders (a class copied from the rig's machine)")
    p.add_argument("--exercises", nargs="+", metavar="PATH", type=Path,
                   help=f"the teacher's exercise files or folders (default: {DEFAULT_EXERCISES})")
    p.add_argument("--daq", metavar="RIG.yaml", nargs="+", dest="grade_daq",
                   help="the DAQ files of the lab's rigs: a rig record must name one of them")
    p.add_argument("--json", action="store_true", help="print a JSON list, one object per record")
    p.add_argument("--csv", metavar="FILE", help="also write the table as CSV, one row per attempt")
    p.add_argument("--figures", metavar="DIR",
                   help="write a figure per exercise (DIR/EXERCISE.png): every attempt's step response "
                   "overlaid, the reference solution dotted")
    p.set_defaults(handler=cmd_grade)


def record_folders(paths: Sequence[str]) -> list[Path]:
    """Each RECORD as given, or the record folders (with result.json) right inside it."""
    out: list[Path] = []
    for p in map(Path, paths):
        if not p.is_dir():
            raise UsageError(f"{p}: not a folder (a record is a folder with result.json)")
        if (p / "result.json").exists():
            out.append(p)
            continue
        inner = sorted(q for q in p.iterdir() if q.is_dir() and (q / "result.json").exists())
        if not inner:
            raise UsageError(f"{p}: no result.json in it or in its folders: not a record")
        out.extend(inner)
    return out


def cmd_grade(args: argparse.Namespace) -> int:
    from quadtank_tui.app.grade import best_attempts, grade_record, load_exercises
    from quadtank_tui.files.exercise import ExerciseError
    from quadtank_tui.files.record import RecordError, digest

    folders = record_folders(args.records)
    try:
        exercises = load_exercises(args.exercises or [DEFAULT_EXERCISES])
    except ExerciseError as exc:
        raise UsageError(str(exc)) from None
    daq_digests = []
    for f in args.grade_daq or []:
        try:
            daq_digests.append(digest(Path(f).read_bytes()))
        except OSError as exc:
            raise UsageError(f"{f}: cannot read: {exc.strerror or exc}") from None
    graded, unread = [], []
    for folder in folders:
        try:
            graded.append(grade_record(folder, exercises, daq_digests=daq_digests))
        except RecordError as exc:
            unread.append(str(exc))
    if args.csv:
        Path(args.csv).write_text(table_csv(graded), encoding="utf-8")
    figures = write_figures(graded, exercises, Path(args.figures)) if args.figures else []
    if args.json:
        print(json.dumps([g.to_dict() for g in graded], indent=2))
    else:
        print(format_table(graded, best_attempts(graded)))
        for f in figures:
            print(f"figure     {f}")
    for line in unread:
        print(f"quadtank: error: {line}", file=__import__("sys").stderr)
    return 2 if unread else 0


def _rep(value: object) -> str:
    return {True: "yes", False: "NO"}.get(value, str(value)) if isinstance(value, bool) else str(value)


def format_table(graded: Sequence[Graded], best: Sequence[Graded]) -> str:
    """One block per attempt (user, exercise, each requirement's figure, verdict and
    whether it was reproduced), then the best attempt per student."""
    lines = []
    for g in graded:
        verdict = "PASSED" if g.passed else "not passed"
        lines.append(f"{g.user:<12} {g.exercise:<14} {g.plant:<9} {g.started:<25} {verdict:<10} "
                     f"reproduced: {_rep(g.reproduced)}   ({g.folder})")
        for r in g.requirements:
            fig = "-" if r.figure is None else f"{r.figure:.4g}"
            lines.append(f"    {r.name:<22} {fig:>10}  limit {r.limit:<8g} {'met' if r.met else 'MISSED':<7}"
                         f" reproduced: {_rep(r.reproduced)}")
        lines.extend(f"    ! {n}" for n in g.notes)
    lines.append("")
    lines.append("best attempt per student")
    lines.append(f"  {'user':<12} {'exercise':<14} {'met':>7}  {'passed':<7} reproduced  record")
    for g in best:
        met = f"{sum(r.met for r in g.requirements)}/{len(g.requirements)}"
        lines.append(f"  {g.user:<12} {g.exercise:<14} {met:>7}  {'yes' if g.passed else 'no':<7} "
                     f"{_rep(g.reproduced):<11} {g.folder}")
    return "\n".join(lines)


def table_csv(graded: Sequence[Graded]) -> str:
    """One row per attempt; per requirement (the union over the records) its figure,
    whether met and whether reproduced."""
    names: list[str] = []
    for g in graded:
        names.extend(r.name for r in g.requirements if r.name not in names)
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["user", "exercise", "record", "started", "plant", "passed", "reproduced",
                *[f"{n} {part}" for n in names for part in ("figure", "met", "reproduced")], "notes"])
    for g in graded:
        by = {r.name: r for r in g.requirements}
        cells: list[object] = []
        for n in names:
            r = by.get(n)
            cells += ["", "", ""] if r is None else ["" if r.figure is None else repr(r.figure), r.met, r.reproduced]
        w.writerow([g.user, g.exercise, str(g.folder), g.started, g.plant, g.passed, g.reproduced, *cells,
                    "; ".join(g.notes)])
    return buf.getvalue()


def write_figures(graded: Sequence[Graded], exercises: Mapping[str, Exercise], folder: Path) -> list[Path]:
    from quadtank_tui.app.grade import reference_curve
    from quadtank_tui.files.figures.exercise import class_figure

    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for ex_id in sorted({g.exercise for g in graded}):
        curves = [(f"{g.user} {g.folder.name} ({'passed' if g.passed else 'not passed'})", g.curve)
                  for g in graded if g.exercise == ex_id and g.curve is not None]
        ex = exercises.get(ex_id)
        ref = reference_curve(ex) if ex is not None else None
        if not curves and ref is None:
            continue
        title = ex.title if ex is not None else ex_id
        out.append(class_figure(title, curves, ref, folder / f"{ex_id}.png"))
    return out
