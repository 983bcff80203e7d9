"""The shared runtime folder read as hostile (issue 41): what lies in it is trusted
for nothing it says.  A FIFO, a link to /dev/zero, a huge sparse file, a record
whose id is a path, an owner field full of terminal escapes: a listing takes a
bounded time and memory, touches nothing outside the folder and prints no control
character.  (Items 3, 4, 5 and 8 of the issue; the ownership checks are in
test_runtime_owners.py.)"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import threading
from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.commands.sessions import format_ended, format_table
from quadtank_tui.files.shared import Untrusted, read_untrusted, shown
from quadtank_tui.session.info import SessionInfo
from quadtank_tui.session.runtime import claim_id, ended_sessions, list_sessions, read_record, user_name, valid_id

ROOT = Path(__file__).resolve().parents[2]


ME = user_name(os.getuid())


def record(**fields: object) -> str:
    """A record of ours (this process's: its file is ours, its pid lives)."""
    base = {"id": f"{ME}-1", "owner": ME, "uid": os.getuid(), "pid": os.getpid(),
            "started": "2026-12-01T10:00:00", "plant": "quadtank"}
    return json.dumps({**base, **fields})


def bounded(what: Callable[[], object], seconds: float = 5.0) -> object:
    """`what()` in a thread; fails the test if it has not returned within `seconds`
    (a FIFO opened for reading blocks forever: the thread is left behind)."""
    got: list[object] = []
    failed: list[BaseException] = []

    def call() -> None:
        try:
            got.append(what())
        except BaseException as exc:  # noqa: BLE001 - raised again in the test's thread
            failed.append(exc)

    t = threading.Thread(target=call, daemon=True)
    t.start()
    t.join(seconds)
    assert not t.is_alive(), f"still blocked after {seconds} s"
    if failed:
        raise failed[0]
    return got[0]


@pytest.mark.parametrize("sid, ok", [("alice-1", True), ("qtr123a-42", True), ("a.b_c-7", True),
                                     ("../victim/b", False), ("/../../tmp/x/a", False), ("a..b-1", False),
                                     (".hidden-1", False), ("alice", False), ("alice-", False),
                                     ("alice-1/", False), ("alice-1\n", False), ("a" * 65 + "-1", False)])
def test_the_id_pattern(sid: str, ok: bool) -> None:
    assert valid_id(sid) is ok


def made(root: Path) -> Path:
    """The runtime folder `root` and this user's place in it (what a first program
    makes, session/folders.py); the place."""
    place = root / "users" / str(os.getuid())
    place.mkdir(parents=True)
    os.chmod(place, 0o755)
    return place


def test_a_record_whose_id_is_a_path_touches_nothing_outside(tmp_path: Path) -> None:
    """Before: root's listing deleted ../victim/b.{sock,json,out} (a record saying
    `"id": "../victim/b"` whose pid was gone) and wrote alice's JSON over a file of
    root's named by `"/../../.../victim/a"`."""
    root, victim = tmp_path / "run", tmp_path / "victim"
    runtime = made(root)
    victim.mkdir()
    for name in ("b.sock", "b.json", "b.out", "a.json"):
        (victim / name).write_text("root's\n")
    dead = subprocess.Popen(["true"])
    dead.wait()
    (runtime / "alice-forged-a.json").write_text(record(id="../victim/b", pid=dead.pid, ended="x",
                                                        ended_at="2020-01-01T00:00:00"))
    (runtime / "alice-forged-b.json").write_text(record(id="/.." * 12 + str(victim / "a"), pid=dead.pid))
    (runtime / f"{ME}-2.json").write_text(record(id="bob-2"))  # another id than its name says
    assert list_sessions(root) == [] and ended_sessions(root) == []
    assert sorted(p.name for p in victim.iterdir()) == ["a.json", "b.json", "b.out", "b.sock"]
    assert all(p.read_text() == "root's\n" for p in victim.iterdir())


def test_a_fifo_a_dev_zero_link_and_a_huge_file_cost_one_fstat(tmp_path: Path) -> None:
    """Before: a FIFO hung the listing (and so `stop`, and a detached session's
    start) for good; /dev/zero grew it to 2.99 GB and a MemoryError; a 1.5 GB
    sparse file cost 11 s and 3 GB."""
    root = tmp_path / "run"
    runtime = made(root)
    os.mkfifo(runtime / "fifo-1.json")
    (runtime / "zero-1.json").symlink_to("/dev/zero")
    with open(runtime / "huge-1.json", "wb") as f:
        f.truncate(1_500_000_000)
    (runtime / f"{ME}-1.json").write_text(record())
    assert [i.id for i in bounded(lambda: list_sessions(root))] == [f"{ME}-1"]  # type: ignore[attr-defined]
    assert bounded(lambda: claim_id(runtime, ME)) == f"{ME}-2"  # what a detached session does first
    for sid in ("fifo-1", "zero-1", "huge-1"):
        assert read_record(runtime, sid) is None


def test_read_untrusted_refuses_links_fifos_devices_others_and_the_oversized(tmp_path: Path) -> None:
    ok = tmp_path / "ok"
    ok.write_bytes(b"x" * 100)
    assert read_untrusted(ok, 100)[0] == b"x" * 100
    (tmp_path / "big").write_bytes(b"y" * 101)
    with pytest.raises(Untrusted, match="101 bytes, more than 100"):
        read_untrusted(tmp_path / "big", 100)
    with pytest.raises(Untrusted, match="not 12345"):
        read_untrusted(ok, 100, owner=12345)
    os.mkfifo(tmp_path / "fifo")
    with pytest.raises(Untrusted, match="not a regular file"):
        bounded(lambda: read_untrusted(tmp_path / "fifo", 100))
    (tmp_path / "link").symlink_to(ok)
    with pytest.raises(OSError):  # ELOOP: a link is never followed
        read_untrusted(tmp_path / "link", 100)
    with pytest.raises(OSError):
        read_untrusted("/dev/zero", 100)


def test_fields_of_the_wrong_type_make_no_record(tmp_path: Path) -> None:
    wrong: list[dict[str, object]] = [{"pid": "1"}, {"uid": True}, {"headless": 1}, {"owner": ["x"]}, {"clients": 1.5}]
    for i, bad in enumerate(wrong, 1):
        (tmp_path / f"{ME}-{i}.json").write_text(record(id=f"{ME}-{i}", **bad))
        assert read_record(tmp_path, f"{ME}-{i}") is None
    (tmp_path / f"{ME}-9.json").write_text("[" * 100_000)  # nested beyond the parser's recursion
    assert read_record(tmp_path, f"{ME}-9") is None
    (tmp_path / f"{ME}-8.json").write_text(record(id=f"{ME}-8"))
    assert read_record(tmp_path, f"{ME}-8") is not None


ESCAPES = "alice\x1b]0;PWNED\x07\x1b[2J\x9b31m\u202e"


def test_what_a_record_says_is_shown_with_its_control_characters_escaped() -> None:
    """Before: an owner `alice\\x1b]0;PWNED\\x07\\x1b[2J` was printed raw (root's
    terminal retitled and cleared)."""
    assert shown(ESCAPES) == "alice\\x1b]0;PWNED\\x07\\x1b[2J\\x9b31m\\u202e"
    assert shown("bob-1 é ü 水") == "bob-1 é ü 水" and shown("a\\x1b") == "a\\\\x1b"
    info = SessionInfo(id="alice-1", owner=ESCAPES, uid=1, pid=1, started="2026-12-01T10:00:00",
                       plant="quad\x1b[2Jtank", note="\x1b[31mred", logging="\r\x00", operator="\x1bc")
    for text in (format_table([info]), format_ended([dataclasses.replace(info, ended="\x1b[2J")])):
        assert not any(ord(c) < 32 or 0x7f <= ord(c) < 0xa0 or c == "\u202e" for c in text.replace("\n", ""))
        assert "alice\\x1b]0;PWNED\\x07" in text


@pytest.mark.wallclock
def test_quadtank_sessions_on_a_hostile_folder(tmp_path: Path) -> None:
    """The command as root would run it, in its own process under a 1 GB address
    space: every attack above at once, answered in one listing, exit 0."""
    root = tmp_path / "run"
    runtime = made(root)
    os.mkfifo(runtime / "fifo.json")
    (runtime / "zero.json").symlink_to("/dev/zero")
    (runtime / f"{ME}-1.json").write_text(record(plant=ESCAPES))
    (runtime / f"{ME}-2.json").write_text(record(id=f"{ME}-2", owner=ESCAPES))  # named to an administrator
    (tmp_path / "victim").mkdir()
    (tmp_path / "victim" / "b.json").write_text("root's\n")
    (runtime / "alice-forged-a.json").write_text(record(id="../victim/b", pid=1 << 22))

    def limit() -> None:
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))

    p = subprocess.run([sys.executable, "-m", "quadtank_tui", "sessions"], capture_output=True, text=True,
                       timeout=30, preexec_fn=limit, cwd=tmp_path,
                       env={**os.environ, "QUADTANK_RUNTIME": str(root), "PYTHONPATH": str(ROOT)})
    assert p.returncode == 0, p.stderr
    assert "\x1b" not in p.stdout and "\x07" not in p.stdout
    lines = p.stdout.splitlines()
    assert lines[0].split()[:2] == ["ID", "OWNER"] and lines[1].split()[:4] == [f"{ME}-1", ME, "2026-12-01", "10:00:00"]
    assert "  alice\\x1b]0;PWNED\\x07" in lines[1]
    assert "names 'alice\\x1b]0;PWNED\\x07" in p.stdout  # root is an administrator: told what was ignored
    assert (tmp_path / "victim" / "b.json").read_text() == "root's\n"


def test_a_lock_records_name_and_session_are_shown_escaped(tmp_path: Path) -> None:
    """A genuine lock record (ours, our live pid) whose user field is escapes and
    whose session is a path: a refusal names it escaped, and no session."""
    from quadtank_tui.files.proc import process_start
    from quadtank_tui.session.lab import LabConfig
    from quadtank_tui.session.lock import holder_of, lock_path

    lab = LabConfig(runtime_dir=tmp_path / "rt")
    device = "192.0.2.9:502/1"
    lock_path(device, lab).write_text(json.dumps({
        "user": ESCAPES, "uid": os.getuid(), "pid": os.getpid(), "start": process_start(os.getpid()),
        "since": "2026-12-01T10:00:00+00:00", "session": "../../victim", "token": "t"}))
    held = holder_of(device, lab)
    assert held is not None and held.session is None and "\x1b" not in str(held)
    assert f"driven by alice\\x1b]0;PWNED\\x07\\x1b[2J\\x9b31m\\u202e (pid {os.getpid()}) since" in str(held)


@pytest.mark.parametrize("pid", [2**31, 2**63, 10**20])
def test_a_record_naming_a_pid_no_kernel_gives_is_of_a_process_gone(tmp_path: Path, pid: int) -> None:
    """A record of the user's own (so it passes every owner check) naming a pid
    beyond pid_max: before, every listing of the folder (root's `quadtank sessions`,
    a serve page) ended in os.kill's OverflowError."""
    from quadtank_tui.files.proc import pid_alive, process_owner, process_start, process_state
    from quadtank_tui.session.folders import own_place, resolve

    assert (process_state(pid), process_owner(pid), process_start(pid), pid_alive(pid)) == ("", None, None, False)
    root = resolve(tmp_path / "rt")
    place = own_place(root.path)
    (place / f"{ME}-1.json").write_text(record(pid=pid, state="Run"))
    assert list_sessions(root.path, prune=False) == []
    assert [i.pid for i in ended_sessions(root.path)] == [pid]


def test_junk_in_users_hides_no_one_elses_place(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A student filled users/ with 20,000 folders: a listing looked at the first
    5,000 entries only (hash order), so another user's place was skipped - their
    sessions unlisted, and their next session went to a new place beside it.  Now
    each owner's entries count against that owner only."""
    from quadtank_tui.session import folders

    monkeypatch.setattr(folders, "MAX_PLACES", 5)  # the junk below stands for 20,000 of them
    root = folders.resolve(tmp_path / "rt")
    junk_owner, other = 54321, 54322
    for i in range(400):
        (root.users / f"j{i:05d}").write_text("")
        os.chown(root.users / f"j{i:05d}", junk_owner, junk_owner)
    place = root.users / str(other)
    place.mkdir(mode=0o755)
    os.chown(place, other, other)
    ignored: list[tuple[str, str]] = []
    assert [(p.path, p.uid) for p in folders.places(root.path, ignored)] == [(place, other)]
    assert len(ignored) == 5  # at most MAX_PLACES named


def test_lab_init_through_a_students_link_makes_nothing(tmp_path: Path) -> None:
    """`lab init STUDENTS_FOLDER/link/rt` with the link (the student's) to a folder
    of root's: the check judged the folders above for the link's owner, so the
    student's folder passed and root made rt (1755, its users/ 1777) wherever the
    link pointed (/etc/rt by hand)."""
    from quadtank_tui.session.folders import RuntimeFolderError, init_lab_folder

    if os.getuid() != 0:
        pytest.skip("needs root (chown)")
    student = 54321
    theirs = tmp_path / "home"
    theirs.mkdir(mode=0o755)
    os.chown(theirs, student, student)
    target = tmp_path / "roots"
    target.mkdir(mode=0o755)
    (theirs / "link").symlink_to(target)
    os.lchown(theirs / "link", student, student)
    with pytest.raises(RuntimeFolderError, match="home is 54321's"):
        init_lab_folder(theirs / "link" / "rt")
    with pytest.raises(RuntimeFolderError, match="home is 54321's"):
        init_lab_folder(theirs / "link" / "deeper" / "rt")
    assert list(target.iterdir()) == []
