"""Exercise files: what a teacher writes is checked, a mistake is one line with its line."""

from __future__ import annotations

from pathlib import Path

import pytest

from quadtank_tui.cli import main
from quadtank_tui.files.exercise import ExerciseError, read_exercise

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted((ROOT / "params" / "exercises").glob("p*.yaml"))

GOOD = """\
title: T
text: |
  Do it.
par: {par}
experiment:
  script: s.yaml
  duration: 100
requirements:
  - overshoot: {{loop: 1, max: 10}}
"""


def test_the_shipped_exercises_read() -> None:
    names = {read_exercise(p).id: read_exercise(p) for p in SHIPPED}
    assert sorted(names) == ["pminus-ident", "pminus-ms", "pminus-pi", "pplus-lesson"]
    pi = names["pminus-pi"]
    assert pi.may_change("CONTROLLER ONE.K") and not pi.may_change("SIMULATION.Valve1")
    assert pi.reference is not None and pi.reference.name == "pminus-pi.par"
    assert [r.name for r in pi.requirements][:2] == ["overshoot 1", "settling_time 1"]
    assert all(e.teacher.strip() for e in names.values())


@pytest.mark.parametrize("change, line, message", [
    ("  - overshot: {loop: 1, max: 10}", 9, "unknown requirement 'overshot'"),
    ("  - overshoot: {loop: 3, max: 10}", 9, "overshoot needs loop: 1 or 2"),
    ("  - overshoot: {loop: 1, max: ten}", 9, "overshoot needs a number max"),
    ("  - settling_time: {loop: 1, band: 2, max: 10}", 9, "band is a share of the step in (0, 1)"),
    ("  - phase_margin: {loop: 1, max: 10}", 9, "phase_margin: unknown setting 'max' (it takes loop, min)"),
])
def test_a_bad_requirement_names_its_line(tmp_path: Path, change: str, line: int, message: str) -> None:
    (tmp_path / "s.yaml").write_text("- {at: 0, state: Run}\n")
    text = GOOD.format(par=ROOT / "params" / "minphase.par").replace("  - overshoot: {loop: 1, max: 10}", change)
    (tmp_path / "e.yaml").write_text(text)
    with pytest.raises(ExerciseError) as err:
        read_exercise(tmp_path / "e.yaml")
    assert err.value.line == line and message in str(err.value)
    assert str(err.value).startswith(f"{tmp_path / 'e.yaml'}, line {line}: ")


def test_unknown_keys_and_missing_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "s.yaml").write_text("- {at: 0, state: Run}\n")
    base = GOOD.format(par=ROOT / "params" / "minphase.par")
    cases = [
        (base.replace("title: T", "title: T\nrunson: rig"), 2, "unknown key 'runson'"),
        (base.replace("script: s.yaml", "script: nothere.yaml"), 6, "experiment.script: no such file"),
        (base + "may_change:\n  keys: [\"CONTROLLER ONE.KK\"]\n", 11, "unknown parameter 'CONTROLLER ONE.KK'"),
        (base.replace("duration: 100", "duration: -5"), 7, "experiment.duration must be seconds"),
    ]
    for text, line, message in cases:
        (tmp_path / "e.yaml").write_text(text)
        assert main(["run", "--exercise", str(tmp_path / "e.yaml"), "--par", "minphase"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"e.yaml, line {line}: " in err and message in err, err


def test_grade_says_a_broken_exercise_in_the_folder_and_skips_its_scripts(tmp_path: Path,
                                                                          capsys: pytest.CaptureFixture[str]) -> None:
    from quadtank_tui.app.grade import load_exercises

    (tmp_path / "s.yaml").write_text("- {at: 0, state: Run}\n")  # a script: skipped
    (tmp_path / "e.yaml").write_text(GOOD.format(par=ROOT / "params" / "minphase.par"))
    assert sorted(load_exercises([tmp_path])) == ["e"]
    (tmp_path / "f.yaml").write_text(GOOD.format(par=ROOT / "params" / "minphase.par").replace("max: 10", "max: x"))
    (tmp_path / "rec").mkdir()
    (tmp_path / "rec" / "result.json").write_text("{}")
    assert main(["grade", str(tmp_path / "rec"), "--exercises", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "f.yaml, line 9: overshoot needs a number max" in err, err

