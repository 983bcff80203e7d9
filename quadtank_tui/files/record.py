"""An attempt's record folder (docs/exercises.md): what a teacher grades.

    DIR/exercise.yaml     the exercise file as it was run (a copy)
    DIR/student.par       the parameters in force at the start (complete: every key)
    DIR/script.yaml       the experiment's script as run (the exercise's or the student's)
    DIR/run.log           the run's log
    DIR/controllers.json  the controllers in force, their loops' Ms and margins, the preview
    DIR/result.json       who, when, where, every requirement's figure and verdict, and the
                          sha256 of each of the files above

Nothing in a record is trusted for what it says: `quadtank grade` checks the
digests, runs a simulator attempt again, and reads a record as a regular file of
bounded size only (files/regular.py).
"""

from __future__ import annotations

import getpass
import hashlib
import json
import os
import platform
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any, Mapping, Sequence

from quadtank_tui import __version__
from quadtank_tui.core.exercise import Verdict
from quadtank_tui.core.parameters import Parameters
from quadtank_tui.files.atomic import atomic_write_text
from quadtank_tui.files.par import format_par
from quadtank_tui.files.regular import read_regular
from quadtank_tui.files.script import Script

FORMAT = "quadtank-exercise-record 1"
#: The files whose digests result.json holds, in this order.
FILES = ("exercise.yaml", "student.par", "script.yaml", "run.log", "controllers.json")
RESULT = "result.json"
#: A record's files: a log of 8 h at 50 ms is ~40 MB; the others are small.
MAX_BYTES = {"run.log": 200_000_000, RESULT: 1_000_000}
DEFAULT_MAX = 5_000_000
#: student.par's `Created on:` (the same text for the same parameters).
PAR_STAMP = datetime(2000, 1, 1)


class RecordError(ValueError):
    """A record that cannot be read: "DIR/FILE: reason"."""


@dataclass(frozen=True)
class RecordFiles:
    folder: Path
    exercise: Path
    params: Parameters
    script: Script | None  # None: an attempt in the TUI, by hand (no script to run again)
    log: Path
    controllers: Mapping[str, Any]
    verdicts: Sequence[Verdict]
    exercise_id: str
    exercise_digest: str
    plant: Mapping[str, Any]
    started: datetime
    ended: datetime
    user: str | None = None
    automatic_since: float | None = None
    summary: str = ""
    seed: int | None = None
    #: "script" (the exercise's experiment), "own run" (the student's script) or
    #: "interactive" (by hand in the TUI: the grader can only read it)
    experiment: str = "script"


def digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def os_user() -> dict[str, Any]:
    """The OS's word on who runs this program (uid and its name), not $USER's."""
    uid = os.getuid()
    try:
        import pwd

        name = pwd.getpwuid(uid).pw_name
    except (KeyError, ImportError):
        name = getpass.getuser()
    return {"name": name, "uid": uid, "host": platform.node()}


def write_record(r: RecordFiles) -> Path:
    """Write the record's files into `r.folder` (the log is already there as
    run.log), result.json last: a folder without it is an attempt that did not end."""
    folder = r.folder
    folder.mkdir(parents=True, exist_ok=True)
    if r.log.resolve() != (folder / "run.log").resolve():
        (folder / "run.log").write_bytes(r.log.read_bytes())
    (folder / "exercise.yaml").write_bytes(r.exercise.read_bytes())
    atomic_write_text(folder / "student.par", format_par(r.params, PAR_STAMP))
    if r.script is not None:
        (folder / "script.yaml").write_bytes(Path(r.script.file).read_bytes())
    else:
        atomic_write_text(folder / "script.yaml", "# an attempt by hand in the TUI (quadtank exercise): no script\n")
    atomic_write_text(folder / "controllers.json", json.dumps(r.controllers, indent=2, default=_plain) + "\n")
    who = os_user()
    if r.user is not None:
        who["name"] = r.user
    result = {
        "format": FORMAT,
        "exercise": {"id": r.exercise_id, "sha256": r.exercise_digest},
        "user": who,
        "program": {"name": "quadtank-tui", "version": __version__},
        "plant": dict(r.plant),
        "started": r.started.isoformat(timespec="seconds"),
        "ended": r.ended.isoformat(timespec="seconds"),
        "seed": r.seed,
        "automatic_since": r.automatic_since,
        "experiment": r.experiment,
        "requirements": [v.to_dict() for v in r.verdicts],
        "passed": all(v.met for v in r.verdicts),
        "summary": r.summary,
        "sha256": {name: digest((folder / name).read_bytes()) for name in FILES},
    }
    atomic_write_text(folder / RESULT, json.dumps(result, indent=2) + "\n")
    return folder


def _plain(x: Any) -> Any:
    if hasattr(x, "tolist"):
        return x.tolist()
    if isinstance(x, complex):
        return [x.real, x.imag]
    return str(x)


def read_file(folder: Path, name: str) -> bytes:
    """One of a record's files, a regular file of bounded size; RecordError."""
    limit = MAX_BYTES.get(name, DEFAULT_MAX)
    try:
        data = read_regular(folder / name, limit)
    except FileNotFoundError:
        raise RecordError(f"{folder / name}: missing") from None
    except OSError as exc:
        raise RecordError(f"{folder / name}: cannot read: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise RecordError(f"{folder / name}: larger than {limit} bytes")
    return data


def read_result(folder: Path) -> dict[str, Any]:
    """result.json, checked for the fields grading needs; RecordError."""
    if not folder.is_dir():
        raise RecordError(f"{folder}: not a record folder")
    try:
        result = json.loads(read_file(folder, RESULT).decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RecordError(f"{folder / RESULT}: not JSON: {exc}") from None
    if not isinstance(result, dict) or result.get("format") != FORMAT:
        raise RecordError(f"{folder / RESULT}: not an exercise record ({FORMAT!r})")
    for key, kind in (("exercise", dict), ("user", dict), ("requirements", list), ("sha256", dict),
                      ("plant", dict)):
        if not isinstance(result.get(key), kind):
            raise RecordError(f"{folder / RESULT}: no {key!r}")
    return result
