"""Bookings (issue 44): the rules of the lab file, what a booking may be, which
files count, and the timeline a session driving the rig follows (SlotWatch), on
explicit times: no clock, no process."""

from __future__ import annotations

import json
import os
from dataclasses import replace
from datetime import datetime, timedelta
from pathlib import Path

import pytest

from quadtank_tui.session import bookings as bk
from quadtank_tui.session.lab import LabConfig, LabConfigError, parse_lab_config

KEYS = ("127.0.0.1:5020/1",)
T0 = datetime(2026, 12, 7, 14, 0).astimezone()  # a Monday


def lab_with(tmp_path: Path, text: str = "") -> LabConfig:
    lab = parse_lab_config(text, name="lab.yaml", source=tmp_path / "lab.yaml")
    return replace(lab, runtime_dir=tmp_path / "rt")


def at(minutes: float) -> datetime:
    return T0 + timedelta(minutes=minutes)


def test_the_rules_and_their_mistakes(tmp_path: Path) -> None:
    r = bk.booking_rules(lab_with(tmp_path, "bookings:\n  slot_minutes: 15\n  warn_minutes: [1, 5]\n"))
    assert (r.slot_minutes, r.horizon_days, r.weekly_quota_minutes, r.warn_minutes) == (15.0, 14.0, 120.0, (5.0, 1.0))
    assert (r.drain_below, r.drain_max_minutes) == (None, 5.0)  # no drain unless the lab asks
    r = bk.booking_rules(lab_with(tmp_path, "bookings:\n  drain_below: 0.2\n  drain_max_minutes: 3\n"))
    assert (r.drain_below, r.drain_max_minutes) == (0.2, 3.0)
    for text, message in (("bookings:\n  slot: 3\n", "lab.yaml:2: bookings.slot: unknown key"),
                          ("bookings:\n  slot_minutes: 7\n", "lab.yaml:2: bookings.slot_minutes: must divide a day"),
                          ("bookings:\n  warn_minutes: 5\n", "lab.yaml:2: bookings.warn_minutes: must be a list"),
                          ("bookings:\n  drain_below: 20\n", "lab.yaml:2: bookings.drain_below: must be a number 0..1")):
        with pytest.raises(LabConfigError) as exc:
            bk.booking_rules(lab_with(tmp_path, text))
        assert str(exc.value).startswith(str(tmp_path / message)), str(exc.value)


def test_a_booking_is_on_the_slots_ahead_and_free(tmp_path: Path) -> None:
    lab = lab_with(tmp_path)
    made = bk.book(lab, KEYS, at(0), at(60), now=at(-10))
    assert (made.user, made.start, made.end, made.rig) == ("root", at(0), at(60), KEYS[0])
    assert made.words().endswith("14:00-15:00") and made.path.stat().st_mode & 0o777 == 0o644
    refusals = {
        "on the lab's slots": (at(10), at(40)),
        "the rig is booked then: root": (at(30), at(90)),
        "before it starts": (at(90), at(60)),
        "that slot is over": (at(-120), at(-60)),
    }
    for words, (start, end) in refusals.items():
        with pytest.raises(bk.BookingError, match=words):
            bk.book(lab, KEYS, start, end, now=at(-10))
    assert [b.id for b in bk.list_bookings(lab, KEYS, now=at(-10))] == [made.id]
    assert bk.in_force(lab, KEYS, at(59)) == made and bk.in_force(lab, KEYS, at(60)) is None
    assert bk.in_force(lab, ("10.0.0.9:502/1",), at(30)) is None  # another rig


def test_a_students_horizon_and_weekly_quota(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    lab = lab_with(tmp_path, "bookings:\n  horizon_days: 2\n  weekly_quota_minutes: 90\n")
    monkeypatch.setattr(bk, "_is_admin", lambda uid, lab: False)
    # this week's Monday: a student's file counts only within the horizon of when the kernel says it was written
    today = datetime.now().astimezone()
    monday = (today - timedelta(days=today.weekday())).replace(hour=14, minute=0, second=0, microsecond=0)

    def at(minutes: float) -> datetime:
        return monday + timedelta(minutes=minutes)

    with pytest.raises(bk.BookingError, match="at most 2 days ahead"):
        bk.book(lab, KEYS, at(3 * 24 * 60), at(3 * 24 * 60 + 30), now=at(0))
    bk.book(lab, KEYS, at(60), at(120), now=at(0))
    with pytest.raises(bk.BookingError, match="that would be 120 min this week; the lab's quota is 90 min"):
        bk.book(lab, KEYS, at(180), at(240), now=at(0))
    bk.book(lab, KEYS, at(180), at(210), now=at(0))  # 90 min: the quota exactly
    with pytest.raises(bk.BookingError, match="needs an administrator"):
        bk.book(lab, KEYS, at(300), at(330), uid=4242, now=at(0))


def test_only_bookings_the_kernel_says_are_theirs_count(tmp_path: Path) -> None:
    lab = lab_with(tmp_path)
    made = bk.book(lab, KEYS, at(0), at(30), now=at(-10))
    forged = made.path.with_name(made.path.name.replace("T140000", "T150000"))
    forged.write_text(json.dumps({"rig": KEYS[0], "uid": 0, "start": at(60).isoformat(), "end": at(90).isoformat()}))
    os.chown(forged, 54321, 54321)  # written by a user who is nobody's administrator, naming root
    big = forged.with_name(forged.name.replace("T150000", "T160000"))
    big.write_text("x" * 5000)
    assert [b.id for b in bk.list_bookings(lab, KEYS, now=at(-10))] == [made.id]
    gone = bk.cancel(lab, made.id)
    assert gone.id == made.id and not made.path.exists() and bk.list_bookings(lab, KEYS, now=at(-10)) == []
    with pytest.raises(bk.BookingError, match="no booking"):
        bk.cancel(lab, made.id)


def _booking(lab: LabConfig, uid: int, start: float, end: float) -> None:
    """A booking of `uid`'s written as an administrator does (root owns the file)."""
    bk.book(lab, KEYS, at(start), at(end), uid=uid, now=at(-60))


def test_the_timeline_of_a_session_on_the_rig(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    lab = lab_with(tmp_path)
    monkeypatch.setattr("quadtank_tui.session.roles.user_name", lambda uid: {1001: "alice", 1002: "bob"}.get(uid, "x"))
    _booking(lab, 1002, 0, 30)    # bob 14:00-14:30
    _booking(lab, 1002, 30, 60)   # and 14:30-15:00: one slot to him
    _booking(lab, 1001, 60, 90)   # alice 15:00-15:30
    alice = bk.SlotWatch(lab, KEYS, 1001)
    bob = bk.SlotWatch(lab, KEYS, 1002)
    # alice, first come before bob's slot: warned 5 and 1 minutes before it, then handed over at its start
    assert alice.step(at(-10)) == (None, None)
    notice, end = alice.step(at(-5))
    assert end is None and alice.fresh and notice is not None and notice.startswith(
        "the rig is booked by bob from 14:00 (in 5 min 00 s): then the pumps go to 0, the log is saved")
    alice.step(at(-4))
    assert not alice.fresh
    alice.step(at(-1))
    assert alice.fresh
    _, end = alice.step(at(0))
    assert end == "the rig's slot of bob began at 14:00; this session handed the rig over"
    assert alice.refusal(at(10)) == "the rig is booked by bob until 15:00; Active needs your own slot (quadtank bookings)"
    # bob: his two slots are one; warned before 15:00, ended at 15:00
    assert bob.refusal(at(10)) is None
    assert bob.step(at(10)) == (None, None)
    notice, end = bob.step(at(55))
    assert end is None and notice is not None and notice.startswith("your slot ends at 15:00 (in 5 min 00 s)")
    _, end = bob.step(at(60))
    assert end == "your slot on the rig ended at 15:00"
    # after the last slot: first come again
    assert bk.SlotWatch(lab, KEYS, 1002).step(at(100)) == (None, None)
    assert alice.refusal(at(100)) is None


def test_a_students_own_files_count_only_as_book_would_have_made_them(tmp_path: Path) -> None:
    """A student writes booking files by hand, all theirs (owner = the uid named):
    only the one `book` could have made counts; nothing else breaks or blocks the list."""
    lab = lab_with(tmp_path)
    folder = bk.bookings_dir(lab)
    now = datetime.now().astimezone().replace(second=0, microsecond=0)
    slot = now.replace(minute=0) + timedelta(hours=1)  # on the 30 min slots, within the horizon
    student = 54321

    def plant(name_start: datetime, body: object, tail: str = "0000000a") -> Path:
        path = folder / f"{bk._stem(KEYS[0])}~{name_start.strftime('%Y%m%dT%H%M%S')}~{student}~{tail}.json"
        path.write_text(body if isinstance(body, str) else json.dumps(body))
        os.chown(path, student, student)
        return path

    def body(start: datetime, end: datetime, rig: str = KEYS[0], uid: object = student) -> dict[str, object]:
        return {"rig": rig, "uid": uid, "start": start.isoformat(), "end": end.isoformat()}

    ever = datetime(2000, 1, 1).astimezone()
    plant(ever, body(ever, datetime(9999, 1, 1).astimezone()))                                # the rig for ever
    plant(slot, body(slot, slot + timedelta(minutes=17)), "0000000b")                              # off the slots
    far = slot + timedelta(days=60)
    plant(far, body(far, far + timedelta(minutes=30)))                                        # past the horizon
    plant(slot, body(slot, slot + timedelta(minutes=30), rig=KEYS[0] + "\x1b]0;PWNED\x07"), "0000000c")  # raw escape
    plant(slot, body(slot, slot + timedelta(minutes=30)), "\x1b[2J")                          # an id that clears
    plant(slot, "[" * 4000, "0000000d")                                                           # RecursionError
    plant(slot, '{"rig": "%s", "uid": Infinity, "start": "%s", "end": "%s"}'
          % (KEYS[0], slot.isoformat(), (slot + timedelta(minutes=30)).isoformat()), "0000000e")
    good = plant(slot + timedelta(hours=1), body(slot + timedelta(hours=1), slot + timedelta(hours=2)), "0000000f")
    over = slot + timedelta(hours=2)  # two more hours that week: past the 120 min quota
    plant(over, body(over, over + timedelta(hours=2)), "00000010")
    found = bk.list_bookings(lab, KEYS, now=now)
    assert [b.id for b in found] == [good.stem]
    assert bk.active_refusal(lab, KEYS, 1000, now + timedelta(minutes=1)) is None
    assert bk.in_force(lab, KEYS, slot + timedelta(minutes=61)) == found[0]


def test_a_folder_flooded_by_one_student_costs_a_bounded_time_and_hides_nobodys(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """50,000 files of one student's made every listing (each second of a session on
    the rig) read every one: 4.4 s a listing.  Now at most MAX_PER_OWNER of one
    student's files are read, and another student's booking is still found."""
    lab = lab_with(tmp_path)
    folder = bk.bookings_dir(lab)
    now = datetime.now().astimezone().replace(second=0, microsecond=0)
    slot = now.replace(minute=0) + timedelta(hours=1)
    flooder, other = 54321, 54322
    name = f"{bk._stem(KEYS[0])}~{slot.strftime('%Y%m%dT%H%M%S')}"
    for i in range(bk.MAX_PER_OWNER * 3):
        junk = folder / f"{name}~{flooder}~{i:08x}.json"
        junk.write_text("{}")
        os.chown(junk, flooder, flooder)
    old = folder / f"{bk._stem(KEYS[0])}~20200101T100000~{flooder}~000000aa.json"  # long past: not even read
    old.write_text("{}")
    os.chown(old, flooder, flooder)
    good = folder / f"{name}~{other}~0000abcd.json"
    good.write_text(json.dumps({"rig": KEYS[0], "uid": other, "start": slot.isoformat(),
                                "end": (slot + timedelta(minutes=30)).isoformat()}))
    os.chown(good, other, other)
    reads: list[Path] = []
    real_read = bk._read

    def counted(path: Path, lab: LabConfig) -> tuple[bk.Booking, float, bool] | None:
        reads.append(path)
        return real_read(path, lab)

    monkeypatch.setattr(bk, "_read", counted)
    assert [b.id for b in bk.list_bookings(lab, KEYS, now=now)] == [good.stem]
    assert len(reads) == bk.MAX_PER_OWNER + 1 and old not in reads


def test_a_fifo_at_the_cancelling_name_neither_hangs_nor_fakes_an_administrators_cancel(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The student whose booking it is makes a FIFO at `<booking>.cancel`: a
    non-root administrator's cancel (unlink refused by the sticky folder) opened it
    for writing and waited for ever.  Now: one clear refusal, at once."""
    import threading

    lab = lab_with(tmp_path)
    made = bk.book(lab, KEYS, at(0), at(30), now=at(-10))
    os.mkfifo(made.path.with_suffix(".cancel"))

    def sticky(path: object) -> None:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(bk.os, "unlink", sticky)
    failed: list[BaseException] = []

    def call() -> None:
        try:
            bk.cancel(lab, made.id)
        except BaseException as exc:  # noqa: BLE001 - looked at in the test's thread
            failed.append(exc)

    t = threading.Thread(target=call, daemon=True)
    t.start()
    t.join(3.0)
    if t.is_alive():  # let the thread go: open the FIFO's other end
        os.close(os.open(made.path.with_suffix(".cancel"), os.O_RDONLY | os.O_NONBLOCK))
        pytest.fail("the cancel waited on the FIFO")
    assert len(failed) == 1 and isinstance(failed[0], bk.BookingError)
    assert "root's file is there, not a cancelling one" in str(failed[0])
    assert [b.id for b in bk.list_bookings(lab, KEYS, now=at(-10))] == [made.id]


def test_a_rig_spelt_otherwise_under_the_same_file_name_books_nothing_over_anothers_slot(tmp_path: Path) -> None:
    """A student's file whose rig field differs from the key only where the file
    name has '_' ('127.0.0.1[5020]1': the same stem) was a rig of its own to the
    overlap check: both counted, and the student's, starting earlier, refused the
    slot's owner Active in their own slot."""
    lab = lab_with(tmp_path)
    now = datetime.now().astimezone().replace(second=0, microsecond=0)
    slot = now.replace(minute=0) + timedelta(hours=2)
    owner, student = 54322, 54321
    mine = bk.book(lab, KEYS, slot, slot + timedelta(minutes=30), uid=owner, now=now)  # root books it for them
    early = slot - timedelta(minutes=30)
    forged = bk.bookings_dir(lab) / f"{bk._stem(KEYS[0])}~{early.strftime('%Y%m%dT%H%M%S')}~{student}~0000beef.json"
    forged.write_text(json.dumps({"rig": KEYS[0].replace(":", "[").replace("/", "]"), "uid": student,
                                  "start": early.isoformat(), "end": (slot + timedelta(minutes=30)).isoformat()}))
    os.chown(forged, student, student)
    assert [b.id for b in bk.list_bookings(lab, KEYS, now=now)] == [mine.id]
    assert bk.active_refusal(lab, KEYS, owner, slot + timedelta(minutes=10)) is None


@pytest.mark.wallclock
def test_a_flock_held_on_bookings_for_ever_delays_a_booking_a_bounded_time(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Anyone who may read bookings/ may flock it: a student's flock held for ever
    made every `quadtank book` wait for ever.  Now it waits FLOCK_WAIT, then books."""
    import fcntl
    import subprocess
    import sys
    import time

    lab = lab_with(tmp_path)
    folder = bk.bookings_dir(lab)
    monkeypatch.setattr(bk, "FLOCK_WAIT", 0.3)
    holder = subprocess.Popen([sys.executable, "-c", "import fcntl, os, sys, time; fd = os.open(sys.argv[1], os.O_RDONLY); "
                               "fcntl.flock(fd, fcntl.LOCK_EX); print(flush=True); time.sleep(30)", str(folder)],
                              stdout=subprocess.PIPE)
    try:
        assert holder.stdout is not None and holder.stdout.readline() == b"\n"
        fd = os.open(folder, os.O_RDONLY)
        with pytest.raises(BlockingIOError):
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # it is held
        os.close(fd)
        t0 = time.monotonic()
        made = bk.book(lab, KEYS, at(0), at(30), now=at(-10))
        assert time.monotonic() - t0 < 2.0 and [b.id for b in bk.list_bookings(lab, KEYS, now=at(-10))] == [made.id]
    finally:
        holder.kill()
        holder.wait()
