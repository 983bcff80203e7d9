"""`quadtank lab` prints the lab configuration in use; `quadtank lab policy` sets the
unattended policy in the lab file, for administrators only.  Users are simulated by
standing in for the role look-ups."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from quadtank_tui.cli import main
from quadtank_tui.session import lab as labmod
from quadtank_tui.session import roles

LAB = """\
# room M:2112
admin_group: teachers   # the teachers' group
unattended:
  keep_while_logging: true
  grace_minutes: 10

runtime_dir: /run/quadtank
"""


@pytest.fixture
def lab_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    path = tmp_path / "lab.yaml"
    path.write_text(LAB)
    monkeypatch.setenv("QUADTANK_LAB", str(path))
    monkeypatch.setattr(roles, "group_id", {"teachers": 60001}.get)
    monkeypatch.setattr(roles, "groups_of", lambda uid: {60001} if uid == 50001 else {60002})
    monkeypatch.setattr(roles, "user_name", {50001: "alice", 50002: "bob"}.get)
    return path


def be(monkeypatch: pytest.MonkeyPatch, user: str) -> None:
    uid = {"alice": 50001, "bob": 50002}[user]
    monkeypatch.setattr(roles, "current_user", lambda: roles.Peer(uid, 60002, os.getpid(), user))


def test_lab_prints_what_is_in_force(lab_file: Path, monkeypatch: pytest.MonkeyPatch,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    be(monkeypatch, "bob")
    assert main(["lab"]) == 0
    assert capsys.readouterr().out == f"""\
lab file        {lab_file}
administrators  member of group teachers
you             bob (uid 50002), administrator: no
runtime dir     /run/quadtank (not there yet: an administrator makes it with `quadtank lab init`)
sessions shared with nobody (owner and administrators)
defaults        {labmod.DEFAULT_PARAMS_DIR / 'default.par'}
unattended      keep_while_logging: yes, grace_minutes: 10
                Unattended, an Active session keeps running while its log is being written and for 10 minutes \
after the last client left (or the log ended), then pauses with the pumps at 0.
                Unattended, a Simul session keeps running until it is stopped.
"""
    be(monkeypatch, "alice")
    assert main(["lab"]) == 0
    assert "you             alice (uid 50001), administrator: yes\n" in capsys.readouterr().out


def test_without_a_lab_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                            capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.delenv("QUADTANK_LAB", raising=False)
    monkeypatch.setenv("QUADTANK_RUNTIME", str(tmp_path / "rt"))
    monkeypatch.setattr(labmod, "SYSTEM_LAB_FILE", tmp_path / "lab.yaml")
    assert main(["lab"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"lab file        none ({tmp_path / 'lab.yaml'} not found: defaults)"
    installed = labmod.DEFAULT_PARAMS_DIR / "default.par"  # the installation's, not ./params
    assert installed == Path(labmod.__file__).parents[2] / "params" / "default.par"
    shown = installed if installed.exists() else installed.parent
    assert out[1] == f"administrators  someone who may write {shown}"
    assert out[3] == f"runtime dir     {tmp_path / 'rt'} (not there yet: your first program makes it, yours alone)"
    (tmp_path / "rt").mkdir(mode=0o755)
    assert main(["lab"]) == 0
    line = capsys.readouterr().out.splitlines()[3]
    if os.getuid() == 0:
        assert line == f"runtime dir     {tmp_path / 'rt'} (the lab's: sessions in {tmp_path / 'rt' / 'users'}/UID, " \
            f"locks in {tmp_path / 'rt' / 'locks'})"


def test_an_administrator_sets_the_policy(lab_file: Path, monkeypatch: pytest.MonkeyPatch,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    be(monkeypatch, "alice")
    assert main(["lab", "policy", "--keep-while-logging", "no", "--grace", "2.5"]) == 0
    assert capsys.readouterr().out == (
        f"{lab_file}: unattended policy set\n"
        "Unattended, an Active session keeps running for 2.5 minutes after the last client left, logging or not, "
        "then pauses with the pumps at 0.\n")
    assert lab_file.read_text() == LAB.replace("true", "false").replace("grace_minutes: 10", "grace_minutes: 2.5")
    assert main(["lab", "policy", "--grace", "0"]) == 0  # one setting; the other stays
    assert labmod.load_lab_config().unattended == labmod.UnattendedPolicy(False, 0.0)


def test_the_policy_block_is_added_where_there_is_none(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                       lab_file: Path) -> None:
    lab_file.write_text("admin_group: teachers\n")
    be(monkeypatch, "alice")
    assert main(["lab", "policy", "--keep-while-logging", "yes"]) == 0
    assert lab_file.read_text() == ("admin_group: teachers\nunattended:\n  keep_while_logging: true\n"
                                    "  grace_minutes: 0\n")  # the grace of the default policy


def test_a_student_may_not(lab_file: Path, monkeypatch: pytest.MonkeyPatch,
                           capsys: pytest.CaptureFixture[str]) -> None:
    be(monkeypatch, "bob")
    assert main(["lab", "policy", "--grace", "60"]) == 2
    assert capsys.readouterr().err == ("quadtank: error: setting the unattended policy needs an administrator "
                                       "(member of group teachers); you are bob\n")
    assert lab_file.read_text() == LAB


@pytest.mark.parametrize("argv, says", [
    (["lab", "policy"], "give --keep-while-logging yes|no and/or --grace MINUTES"),
    (["lab", "policy", "--grace", "-1"], "--grace must be 0..1440, got -1"),
    (["lab", "policy", "--grace", "nan"], "--grace must be a number of minutes, got nan"),
])
def test_bad_policy_options(argv: list[str], says: str, lab_file: Path, monkeypatch: pytest.MonkeyPatch,
                            capsys: pytest.CaptureFixture[str]) -> None:
    be(monkeypatch, "alice")
    assert main(argv) == 2
    assert capsys.readouterr().err == f"quadtank: error: {says}\n"
    assert lab_file.read_text() == LAB


def test_a_broken_lab_file_is_one_line(lab_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lab_file.write_text("admin_group: teachers\nunattended:\n  grace_minutes: soon\n")
    assert main(["lab"]) == 2
    assert capsys.readouterr().err == (f"quadtank: error: {lab_file}:3: unattended.grace_minutes: must be a "
                                       "number of minutes 0..1440, got 'soon'\n")


def test_an_unwritable_lab_file_is_one_line(tmp_path: Path, lab_file: Path, monkeypatch: pytest.MonkeyPatch,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """An administrator by group who may not write the file itself (root may write anything,
    so the write is made to fail as the file system would)."""
    from quadtank_tui.files import atomic

    def refuse(*args: object, **kwargs: object) -> None:
        raise PermissionError(13, "Permission denied", str(lab_file))

    monkeypatch.setattr(atomic, "atomic_write_text", refuse)
    be(monkeypatch, "alice")
    assert main(["lab", "policy", "--grace", "5"]) == 2
    assert capsys.readouterr().err == (f"quadtank: error: {lab_file}: cannot write the lab file: Permission denied; "
                                       "an administrator needs write access to it (or name another file with "
                                       "$QUADTANK_LAB)\n")
    assert lab_file.read_text() == LAB
