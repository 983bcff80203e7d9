"""`quadtank book RIG FROM TO` and `quadtank bookings`: the rig's time in slots
(session/bookings.py; docs/serve.md)."""

from __future__ import annotations

import argparse
import json
import pwd

from typing import TYPE_CHECKING, Callable

from quadtank_tui.commands import UsageError

if TYPE_CHECKING:
    from quadtank_tui.session.lab import LabConfig


def add_parsers(sub: argparse._SubParsersAction) -> None:
    b = sub.add_parser("book", help="book a rig's time: a slot from FROM to TO",
                       description="Book the rig a DAQ configuration names (as --daq) from FROM to TO, on the "
                       "lab's slots (lab file: bookings.slot_minutes), within its horizon and weekly quota. During "
                       "your slot nobody else may put the rig in Active; at its end the rig is handed over.")
    b.add_argument("rig", metavar="RIG", help="the rig: its DAQ configuration file or preset (as --daq)")
    b.add_argument("start", metavar="FROM", help="HH:MM (today) or YYYY-MM-DD HH:MM, local time")
    b.add_argument("end", metavar="TO", help="HH:MM (today) or YYYY-MM-DD HH:MM, local time")
    b.add_argument("--for", dest="for_user", metavar="USER", help="book for USER (administrators only)")
    b.add_argument("--lab", metavar="FILE", help="the lab file (default $QUADTANK_LAB, else /etc/quadtank/lab.yaml)")
    b.set_defaults(handler=cmd_book)
    s = sub.add_parser("bookings", help="list the rigs' bookings; cancel one",
                       description="The bookings of every rig (or of RIG), from the last week on: id, rig, whose, "
                       "from, to, who booked it.")
    s.add_argument("--rig", metavar="RIG", help="only this rig's (its DAQ configuration file or preset)")
    s.add_argument("--cancel", metavar="ID", help="cancel booking ID (yours; administrators: anyone's)")
    s.add_argument("--json", action="store_true", help="one JSON list")
    s.add_argument("--lab", metavar="FILE", help="the lab file (default $QUADTANK_LAB, else /etc/quadtank/lab.yaml)")
    s.set_defaults(handler=cmd_bookings)


def _lab(path: str | None) -> LabConfig:
    from quadtank_tui.session.lab import LabConfigError, load_lab_config

    try:
        return load_lab_config(path)
    except LabConfigError as exc:
        raise UsageError(str(exc)) from None


def rig_keys_of(rig: str) -> tuple[str, ...]:
    from quadtank_tui.daq.open import load_rig_config
    from quadtank_tui.session.riglock import rig_keys

    try:
        return rig_keys(load_rig_config(rig))
    except (OSError, ValueError) as exc:
        raise UsageError(f"{rig}: {exc}") from None


def cmd_book(args: argparse.Namespace) -> int:
    from quadtank_tui.session.bookings import BookingError, book, parse_when
    from quadtank_tui.session.lab import LabConfigError

    lab = _lab(args.lab)
    keys = rig_keys_of(args.rig)
    uid = None
    if args.for_user:
        try:
            uid = pwd.getpwnam(args.for_user).pw_uid
        except KeyError:
            raise UsageError(f"--for {args.for_user}: no such user on this machine") from None
    try:
        start = parse_when(args.start)
        end = parse_when(args.end, today=start)
        if end <= start and len(args.end.strip()) <= 8:
            from datetime import timedelta

            end += timedelta(days=1)  # 23:30 00:30: past midnight
        made = book(lab, keys, start, end, uid=uid)
    except (BookingError, LabConfigError) as exc:
        raise UsageError(str(exc)) from None
    except OSError as exc:
        raise UsageError(f"the bookings folder: {exc}") from None
    print(f"booked {made.id}: {made.words()} on {', '.join(keys)}")
    return 0


def cmd_bookings(args: argparse.Namespace) -> int:
    from quadtank_tui.session.bookings import BookingError, as_json, cancel, list_bookings

    lab = _lab(args.lab)
    if args.cancel:
        try:
            gone = cancel(lab, args.cancel)
        except BookingError as exc:
            raise UsageError(str(exc)) from None
        print(f"cancelled {gone.id}: {gone.words()}")
        return 0
    keys = rig_keys_of(args.rig) if args.rig else None
    found = list_bookings(lab, keys)
    if args.json:
        print(json.dumps([as_json(b) for b in found], indent=2))
        return 0
    if not found:
        print("no bookings")
        return 0
    for b in found:
        by = "" if b.by == b.user else f"  (booked by {b.by})"
        print(f"{b.id}  {b.rig}  {b.user}  {b.start:%Y-%m-%d %H:%M:%S} - {b.end:%H:%M:%S}{by}")
    return 0


def refuse_in_anothers_slot(rig: str) -> None:
    """UsageError if the rig (a DAQ configuration) is in someone else's booked slot
    now: a program that would drive it is refused before it takes the lock (a bad
    file or an unresolved host is left to the lock, which says so)."""
    import os

    from quadtank_tui.session.bookings import active_refusal
    from quadtank_tui.session.lab import LabConfigError, load_lab_config

    try:
        keys = rig_keys_of(rig)
        why = active_refusal(load_lab_config(), keys, os.getuid())
    except (UsageError, LabConfigError, OSError, ValueError):
        return
    if why is not None:
        raise UsageError(why.replace("; Active needs", "; driving it needs"))


def slot_end_watch(rig: str, *, every: float = 1.0) -> Callable[[], str | None] | None:
    """For a foreground run driving `rig`: a callable asked ahead of every sample
    that reads the bookings once a second (`every`, wall time), says each of the
    lab's warnings on stderr, and returns why the run must end now (its user's slot
    is over, or someone else's began), else None.  None if the rig or the lab file
    cannot be read (the lock and the start's refusal say so, not this)."""
    import os
    import time
    from datetime import datetime

    from quadtank_tui.commands import say
    from quadtank_tui.session.bookings import SlotWatch
    from quadtank_tui.session.lab import LabConfigError, load_lab_config

    try:
        watch = SlotWatch(load_lab_config(), rig_keys_of(rig), os.getuid())
    except (UsageError, LabConfigError, OSError, ValueError):
        return None
    due = 0.0

    def until() -> str | None:
        nonlocal due
        now = time.monotonic()
        if now < due:
            return None
        due = now + every
        try:
            notice, end = watch.step()
        except (OSError, ValueError) as exc:  # an unreadable bookings folder stops nobody
            say(f"quadtank: bookings: {exc}")
            return None
        if watch.fresh and notice:
            say(f"quadtank: {datetime.now():%H:%M:%S} slot: {notice.replace('this session stops', 'this run stops')}")
        if end is not None:
            say(f"quadtank: {datetime.now():%H:%M:%S} slot: {end}: pumps at 0, the log is saved, this run stops")
        return end

    return until
