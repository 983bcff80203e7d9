"""Bookings: a rig's time in slots, kept where the sessions and locks are.

```yaml
bookings:
  slot_minutes: 30             # slots start at midnight and every slot_minutes after
  horizon_days: 14             # how far ahead a student may book
  weekly_quota_minutes: 120    # per student per ISO week (administrators: none)
  warn_minutes: [5, 1]         # the holder's screen is warned this long before the end
  drain_below: 0.2             # optional: at the end, pumps off until every level is under this
  drain_max_minutes: 5         #   (normalized 0..1), at most this long; then the session stops
```

A booking is a file `runtime_dir/bookings/<rig>~<start>~<uid>~<random>.json` (the folder
1777 and sticky, like locks/): the kernel says who wrote it (its owner), and it
counts only if that owner is the user it names, or root, or an administrator (who
books for anyone).  Nobody else may remove or rewrite it (sticky folder, 0644);
its owner or root cancels it by removing it, an administrator by a cancelling
file of their own beside it (`.cancel`).  Overlapping bookings are refused when
made, under the folder's flock; of two that still overlap (one written without
the flock), the one the kernel created first (ctime) counts.

The rig is named by its lock keys (session/riglock.rig_keys): a booking under any
key of a rig books the rig.  What the bookings decide (`in_force`): outside a
slot held by someone else, the rig is free as without bookings (first come);
inside one, Active is refused to everyone else with who holds it and until when,
and a session driving the rig then is handed over (session/host.py: warnings,
pumps at 0, the log saved, the session stopped).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
import stat
from dataclasses import dataclass
from datetime import date, datetime, timedelta
from pathlib import Path
from typing import Any, Iterable

from quadtank_tui.session.lab import LabConfig, LabConfigError, ensure_runtime_dir
from quadtank_tui.session.lock import flock_within

KEYS = ("slot_minutes", "horizon_days", "weekly_quota_minutes", "warn_minutes", "drain_below", "drain_max_minutes")
#: Ended bookings are kept (listed) this long, then removed by their owner's next booking.
KEPT = timedelta(days=7)
#: Seconds `book` waits for the bookings folder's flock (an honest holder's is
#: milliseconds) before it goes on without it.
FLOCK_WAIT = 3.0
#: Largest booking file read: anything bigger is not one of ours.
MAX_FILE = 4096
#: A booking file's name as `book` makes it: <rig>~<start>~<uid>~<8 hex digits>.json.
FILE_NAME = re.compile(r"([^~]{1,255})~([0-9]{8}T[0-9]{6})~([0-9]{1,10})~[0-9a-f]{8}\.json")
#: Files of one student (not an administrator) read by a listing: bookings/ filled
#: with junk of theirs costs a bounded time (counted per owner after lstat, so one
#: student's junk never hides another's booking).
MAX_PER_OWNER = 200


class BookingError(ValueError):
    """A booking refused; the message says why."""


@dataclass(frozen=True)
class BookingRules:
    slot_minutes: float = 30.0
    horizon_days: float = 14.0
    weekly_quota_minutes: float = 120.0
    warn_minutes: tuple[float, ...] = (5.0, 1.0)
    #: the drain at a hand-over: every level under this (normalized), None: no drain
    drain_below: float | None = None
    drain_max_minutes: float = 5.0

    @property
    def slot(self) -> timedelta:
        return timedelta(minutes=self.slot_minutes)


def booking_rules(lab: LabConfig) -> BookingRules:
    """The lab file's `bookings:` section, checked (LabConfigError with file, line, key)."""
    data = lab.sections.get("bookings", {})
    name = str(lab.source) if lab.source else "<lab config>"

    def fail(key: str, reason: str) -> LabConfigError:
        return LabConfigError(name, reason, key=f"bookings.{key}",
                              line=lab.lines.get(f"bookings.{key}", lab.lines.get("bookings")))

    for k in data:
        if k not in KEYS:
            raise fail(str(k), f"unknown key; expected one of {', '.join(KEYS)}")

    def number(key: str, default: float, low: float, high: float) -> float:
        value = data.get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= high:
            raise fail(key, f"must be a number {low:g}..{high:g}, got {value!r}")
        return float(value)

    slot = number("slot_minutes", 30.0, 1 / 60 - 1e-9, 24 * 60.0)
    if (24 * 60 * 60) % round(slot * 60) != 0 or abs(slot * 60 - round(slot * 60)) > 1e-6:
        raise fail("slot_minutes", f"must divide a day into whole slots of whole seconds, got {slot:g}")
    warn = data.get("warn_minutes", [5, 1])
    if not isinstance(warn, list) or not all(isinstance(w, (int, float)) and not isinstance(w, bool)
                                             and 0 < w <= 120 for w in warn):
        raise fail("warn_minutes", "must be a list of minutes 0..120 before a slot's end, e.g. [5, 1]")
    drain = number("drain_below", 0.5, 0.0, 1.0) if "drain_below" in data else None
    return BookingRules(slot, number("horizon_days", 14.0, 0.0, 366.0),
                        number("weekly_quota_minutes", 120.0, 0.0, 7 * 24 * 60.0),
                        tuple(sorted((float(w) for w in warn), reverse=True)), drain,
                        number("drain_max_minutes", 5.0, 0.0, 120.0))


@dataclass(frozen=True)
class Booking:
    rig: str          # the lock key it was made under
    uid: int          # whose slot it is
    user: str
    start: datetime   # aware, local
    end: datetime
    by: str           # who wrote it (the file's owner's name)
    path: Path

    @property
    def id(self) -> str:
        return self.path.stem

    def words(self) -> str:
        day = "" if self.start.date() == datetime.now().astimezone().date() else f"{self.start:%Y-%m-%d} "
        return f"{self.user} {day}{_hms(self.start)}-{_hms(self.end)}"


def bookings_dir(lab: LabConfig) -> Path:
    """bookings/ of the runtime folder in force (session/folders.py: the lab's is
    made by `quadtank lab init`, root's, 1777 sticky)."""
    return ensure_runtime_dir(lab).bookings


def _stem(key: str) -> str:
    return "".join(c if c.isalnum() or c in ".-" else "_" for c in key)


def _is_admin(uid: int, lab: LabConfig) -> bool:
    from quadtank_tui.session.roles import is_administrator

    return uid == 0 or is_administrator(uid, lab)


def _read(path: Path, lab: LabConfig) -> tuple[Booking, float, bool] | None:
    """The booking in `path` if it is genuine (see the module docstring), its ctime,
    and whether an administrator (or root) wrote it."""
    from quadtank_tui.session.roles import user_name

    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_size > MAX_FILE:
            return None
        data = json.loads(os.read(fd, MAX_FILE).decode("utf-8"))
        rig, uid, start, end = data["rig"], data["uid"], data["start"], data["end"]
        if not (isinstance(rig, str) and isinstance(uid, int) and isinstance(start, str) and isinstance(end, str)):
            return None
        if not (rig.isprintable() and path.name.isprintable()):
            return None  # what is shown of it (its id, its rig) on others' terminals carries no control character
        if st.st_uid != uid and not _is_admin(st.st_uid, lab):
            return None  # written by someone who may not book for that user
        b = Booking(rig, uid, user_name(uid), datetime.fromisoformat(start), datetime.fromisoformat(end),
                    user_name(st.st_uid), path)
        if b.start.tzinfo is None or b.end <= b.start or not path.stem.startswith(_name(rig, b.start, uid) + "~"):
            return None
        return b, st.st_ctime, _is_admin(st.st_uid, lab)
    except (OSError, ValueError, KeyError, TypeError, RecursionError, OverflowError):
        return None  # (a UnicodeDecodeError is a ValueError; RecursionError: '[' nested 4096 deep)
    finally:
        os.close(fd)


def _name(rig: str, start: datetime, uid: int) -> str:
    return f"{_stem(rig)}~{start.strftime('%Y%m%dT%H%M%S')}~{uid}"


def _cancelled(path: Path, lab: LabConfig) -> bool:
    cancel = path.with_suffix(".cancel")
    try:
        st = os.lstat(cancel)
    except OSError:
        return False
    return stat.S_ISREG(st.st_mode) and _is_admin(st.st_uid, lab)


def list_bookings(lab: LabConfig, keys: Iterable[str] | None = None, *,
                  now: datetime | None = None) -> list[Booking]:
    """The genuine bookings (of the rig with lock keys `keys`, else of every rig)
    that end after now - KEPT, in order of start; of overlapping ones on a rig,
    the first created only."""
    folder = bookings_dir(lab)
    rules = booking_rules(lab)
    wanted = None if keys is None else {_stem(k) for k in keys}
    now = now or datetime.now().astimezone()
    found: list[tuple[Booking, float, bool]] = []
    # a student's file matters only if it starts in this window (its rules: at most
    # horizon_days ahead, at most the weekly quota long; a day's slack for time zones)
    local = now.astimezone().replace(tzinfo=None)
    first = local - KEPT - timedelta(minutes=rules.weekly_quota_minutes, days=1)
    last = local + timedelta(days=rules.horizon_days + 1)
    admins: dict[int, bool] = {}
    per_owner: dict[int, int] = {}
    try:
        entries = os.scandir(folder)
    except OSError:
        return []
    with entries:
        for entry in entries:
            m = FILE_NAME.fullmatch(entry.name)
            if m is None or (wanted is not None and m.group(1) not in wanted):
                continue
            try:
                st = entry.stat(follow_symlinks=False)
                t = m.group(2)  # not strptime: its module is imported lazily, after a tab's drop
                named = datetime(int(t[:4]), int(t[4:6]), int(t[6:8]), int(t[9:11]), int(t[11:13]), int(t[13:]))
            except (OSError, ValueError):
                continue
            if not stat.S_ISREG(st.st_mode):
                continue
            if st.st_uid not in admins:
                admins[st.st_uid] = _is_admin(st.st_uid, lab)
            if not admins[st.st_uid]:  # nobody's junk costs more than MAX_PER_OWNER reads, nor hides another's
                if not first <= named <= last:
                    continue
                per_owner[st.st_uid] = per_owner.get(st.st_uid, 0) + 1
                if per_owner[st.st_uid] > MAX_PER_OWNER:
                    continue
            got = _read(Path(entry.path), lab)
            if got is None or got[0].end < now - KEPT or _cancelled(Path(entry.path), lab):
                continue
            found.append(got)
    found.sort(key=lambda f: f[1])  # first created first
    kept: list[Booking] = []
    used: dict[tuple[str, int, date], timedelta] = {}
    for b, ctime, by_admin in found:
        if not by_admin and not _within_rules(b, ctime, rules, used):
            continue
        # one rig per file-name stem: a rig field spelt otherwise under the same stem is no other rig
        if not any(_stem(o.rig) == _stem(b.rig) and o.start < b.end and b.start < o.end for o in kept):
            kept.append(b)
    return sorted(kept, key=lambda b: (b.start, b.rig))


def _within_rules(b: Booking, ctime: float, rules: BookingRules,
                  used: dict[tuple[str, int, date], timedelta]) -> bool:
    """Whether a student's own booking file is one `book` could have made: on the
    lab's slots, at most horizon_days ahead of when it was written (its ctime, the
    kernel's), within the weekly quota (`used`: each rig key's, user's and week's
    time so far, the files written first counted first).  A file written by hand
    past the rules (the rig booked for years) counts for nothing."""
    start, end = b.start.astimezone(), b.end.astimezone()
    if not (_aligned(start, rules) and _aligned(end, rules)):
        return False
    if start > datetime.fromtimestamp(ctime).astimezone() + timedelta(days=rules.horizon_days):
        return False
    week = (_stem(b.rig), b.uid, start.date() - timedelta(days=start.weekday()))
    total = used.get(week, timedelta()) + (end - start)
    if total > timedelta(minutes=rules.weekly_quota_minutes):
        return False
    used[week] = total
    return True


def in_force(lab: LabConfig, keys: Iterable[str], when: datetime | None = None) -> Booking | None:
    """The booking of the rig (any of `keys`) whose slot holds `when` (None: the rig is not booked then)."""
    when = when or datetime.now().astimezone()
    for b in list_bookings(lab, keys, now=when):
        if b.start <= when < b.end:
            return b
    return None


def next_booking(lab: LabConfig, keys: Iterable[str], after: datetime) -> Booking | None:
    return next((b for b in list_bookings(lab, keys, now=after) if b.start >= after), None)


def active_refusal(lab: LabConfig, keys: Iterable[str], uid: int, when: datetime | None = None) -> str | None:
    """Why `uid` may not drive the rig now (None: it may): someone else's slot."""
    when = when or datetime.now().astimezone()
    bookings = list_bookings(lab, keys, now=when)
    b = next((b for b in bookings if b.start <= when < b.end), None)
    if b is None or b.uid == uid:
        return None
    end = b.end
    for o in bookings:  # the holder's contiguous slots are one
        if o.uid == b.uid and o.start == end:
            end = o.end
    return f"the rig is booked by {b.user} until {_hms(end)}; Active needs your own slot (quadtank bookings)"


def _aligned(t: datetime, rules: BookingRules) -> bool:
    seconds = t.hour * 3600 + t.minute * 60 + t.second
    return t.microsecond == 0 and seconds % round(rules.slot_minutes * 60) == 0


def book(lab: LabConfig, keys: tuple[str, ...], start: datetime, end: datetime, *, uid: int | None = None,
         now: datetime | None = None) -> Booking:
    """Book the rig (lock keys `keys`) from `start` to `end` for `uid` (default: the
    caller; another user's only by an administrator).  BookingError saying why not."""
    from quadtank_tui.session.roles import user_name

    rules = booking_rules(lab)
    me = os.getuid()
    uid = me if uid is None else uid
    admin = _is_admin(me, lab)
    if uid != me and not admin:
        raise BookingError(f"booking for {user_name(uid)} needs an administrator; you are {user_name(me)}")
    now = now or datetime.now().astimezone()
    if end <= start:
        raise BookingError(f"the slot ends ({end:%Y-%m-%d %H:%M:%S}) before it starts ({start:%Y-%m-%d %H:%M:%S})")
    if not _aligned(start, rules) or not _aligned(end, rules):
        raise BookingError(f"a booking starts and ends on the lab's slots: every {rules.slot_minutes:g} min "
                           "from midnight")
    if end <= now:
        raise BookingError(f"that slot is over (it ended at {end:%H:%M:%S})")
    if not admin and start > now + timedelta(days=rules.horizon_days):
        raise BookingError(f"a student books at most {rules.horizon_days:g} days ahead")
    folder = bookings_dir(lab)
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    try:
        flock_within(fd, FLOCK_WAIT)  # had or not: of two overlapping bookings the first written counts
        existing = list_bookings(lab, keys, now=now)
        for o in existing:
            if o.start < end and start < o.end:
                raise BookingError(f"the rig is booked then: {o.words()}")
        if not admin:
            week = start.date() - timedelta(days=start.weekday())
            used = sum(((o.end - o.start) for o in existing if o.uid == uid
                        and o.start.date() - timedelta(days=o.start.weekday()) == week), timedelta())
            if used + (end - start) > timedelta(minutes=rules.weekly_quota_minutes):
                raise BookingError(f"that would be {(used + end - start).total_seconds() / 60:g} min this week; "
                                   f"the lab's quota is {rules.weekly_quota_minutes:g} min a student")
        made = []
        try:
            for key in keys:
                # a random tail: a name nobody can take first (a student's file of that name would block it)
                path = folder / f"{_name(key, start, uid)}~{secrets.token_hex(4)}.json"
                text = json.dumps({"rig": key, "uid": uid, "start": start.isoformat(), "end": end.isoformat(),
                                   "made": now.isoformat(timespec="seconds")})
                out = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
                made.append(path)
                with os.fdopen(out, "w") as f:
                    f.write(text)
                os.chmod(path, 0o644)
        except FileExistsError:
            for p in made:
                with contextlib.suppress(OSError):
                    os.unlink(p)
            raise BookingError("a booking file of that slot is there already (quadtank bookings)") from None
    finally:
        os.close(fd)
    got = _read(made[0], lab)
    assert got is not None
    return got[0]


def cancel(lab: LabConfig, booking_id: str) -> Booking:
    """Cancel the booking `booking_id` (and its other keys' files): its owner, root,
    or an administrator (a .cancel file of theirs).  BookingError otherwise."""
    from quadtank_tui.session.roles import user_name

    me = os.getuid()
    target = next((b for b in list_bookings(lab) if b.id == booking_id), None)
    if target is None:
        raise BookingError(f"no booking {booking_id!r} (quadtank bookings lists them)")
    if target.uid != me and not _is_admin(me, lab):
        raise BookingError(f"booking {booking_id} is {target.user}'s; cancelling it needs an administrator; "
                           f"you are {user_name(me)}")
    twins = [b for b in list_bookings(lab) if b.uid == target.uid and b.start == target.start]
    for b in twins:
        try:
            os.unlink(b.path)
        except PermissionError:  # an administrator, not its writer: a cancelling file of theirs
            _cancel_file(b.path.with_suffix(".cancel"), lab)
        except FileNotFoundError:
            pass
    return target


def _cancel_file(path: Path, lab: LabConfig) -> None:
    """A new cancelling file of ours at `path`.  Made with O_EXCL: whatever the
    booking's writer put at that name first (a FIFO an open would wait on for
    ever, a file of theirs) is never opened; BookingError names it."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC,
                     0o644)
    except FileExistsError:
        if _cancelled(path.with_suffix(".json"), lab):
            return  # cancelled already
        from quadtank_tui.session.roles import user_name

        try:
            owner = user_name(os.lstat(path).st_uid)
        except OSError:
            owner = "someone"
        raise BookingError(f"{path.name}: {owner}'s file is there, not a cancelling one; root cancels this "
                           "booking (sudo quadtank bookings --cancel ID removes it)") from None
    os.close(fd)


def parse_when(text: str, *, today: datetime | None = None) -> datetime:
    """`HH:MM[:SS]` (today), `YYYY-MM-DD HH:MM[:SS]` or `YYYY-MM-DDTHH:MM[:SS]`, local time."""
    today = today or datetime.now().astimezone()
    t = text.strip()
    try:
        if len(t) <= 8 and ":" in t:
            parts = [int(p) for p in t.split(":")]
            if len(parts) not in (2, 3):
                raise ValueError
            h, m, s = (parts + [0])[:3]
            return today.replace(hour=h, minute=m, second=s, microsecond=0)
        when = datetime.fromisoformat(t.replace(" ", "T"))
    except ValueError:
        raise BookingError(f"{text!r} is not a time: HH:MM, or YYYY-MM-DD HH:MM") from None
    return when.astimezone() if when.tzinfo is None else when


def as_json(b: Booking) -> dict[str, Any]:
    return {"id": b.id, "rig": b.rig, "user": b.user, "uid": b.uid, "start": b.start.isoformat(),
            "end": b.end.isoformat(), "by": b.by}


class SlotWatch:
    """What the bookings mean for one session driving a rig (lock keys `keys`) as
    `uid`: `refusal()` for Active, and `step(now)` each second -> (the notice for its
    screens, or None; why it must hand the rig over now, or None).

    The session's time on the rig ends at the end of its user's slot (contiguous
    slots of theirs count as one) or, first come without a slot, at the start of
    someone else's; each of `rules.warn_minutes` before that end gives a notice."""

    def __init__(self, lab: LabConfig, keys: tuple[str, ...], uid: int) -> None:
        self.lab, self.keys, self.uid = lab, keys, uid
        self.rules = booking_rules(lab)
        self._slot_end: datetime | None = None
        self.notice: str | None = None
        #: a warning given by the last step (the first past each of warn_minutes)
        self.fresh = False
        self._warned: set[float] = set()
        # a session that starts in its user's slot ends with it, even if its first step comes after the end
        now = datetime.now().astimezone()
        bookings = list_bookings(lab, keys, now=now)
        own = next((b for b in bookings if b.start <= now < b.end and b.uid == uid), None)
        if own is not None:
            self._slot_end = self._own_end(own, bookings)

    def refusal(self, now: datetime | None = None) -> str | None:
        return active_refusal(self.lab, self.keys, self.uid, now)

    def _own_end(self, first: Booking, bookings: list[Booking]) -> datetime:
        end = first.end
        for b in bookings:
            if b.uid == self.uid and b.start == end:
                end = b.end
        return end

    def step(self, now: datetime | None = None) -> tuple[str | None, str | None]:
        now = now or datetime.now().astimezone()
        self.fresh = False
        bookings = list_bookings(self.lab, self.keys, now=now)
        current = next((b for b in bookings if b.start <= now < b.end), None)
        if self._slot_end is not None and now >= self._slot_end:
            return self.notice, f"your slot on the rig ended at {_hms(self._slot_end)}"
        if current is not None and current.uid != self.uid:
            return self.notice, (f"the rig's slot of {current.user} began at {_hms(current.start)}; "
                                 "this session handed the rig over")
        if current is not None:
            self._slot_end = self._own_end(current, bookings)
        if self._slot_end is not None and now >= self._slot_end:
            return self.notice, f"your slot on the rig ended at {_hms(self._slot_end)}"
        if self._slot_end is not None:
            end, what = self._slot_end, f"your slot ends at {_hms(self._slot_end)}"
        else:
            nxt = next((b for b in bookings if b.start > now and b.uid != self.uid), None)
            if nxt is None:
                self.notice = None
                self._warned.clear()
                return None, None
            end, what = nxt.start, f"the rig is booked by {nxt.user} from {_hms(nxt.start)}"
        left = (end - now).total_seconds()
        due = {w for w in self.rules.warn_minutes if left <= w * 60}
        self.fresh = bool(due - self._warned)
        self._warned |= due
        if due:
            self.notice = (f"{what} (in {_left(left)}): then the pumps go to 0, the log is saved and this "
                           "session stops")
        return self.notice, None


def _hms(t: datetime) -> str:
    return f"{t:%H:%M:%S}".removesuffix(":00") if t.second == 0 else f"{t:%H:%M:%S}"


def _left(seconds: float) -> str:
    s = max(int(round(seconds)), 0)
    return f"{s // 60} min {s % 60:02d} s" if s >= 60 else f"{s} s"
