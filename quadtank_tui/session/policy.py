"""What an Active session does while no client is attached: a pure decision the
session process acts on, and the sentence shown when one detaches.

A Simul session always keeps running (nothing physical can go wrong).  An Active
one drives real pumps with nobody watching the screen: without a policy from an
administrator it pauses with the pumps at 0 as soon as the last client leaves
("Active without policy: pumps at 0").  A lab that wants an hour's
identification experiment to survive a dropped link sets keep_while_logging and a
grace period in its lab file (`quadtank lab policy`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

#: The longest grace an administrator may set: a day.
MAX_GRACE_MINUTES = 24 * 60.0

Action = Literal["keep", "pause"]


@dataclass(frozen=True)
class UnattendedPolicy:
    """The lab's rule for unattended Active sessions (set by an administrator).

    keep_while_logging: an Active session whose log is being written keeps running.
    grace_minutes: minutes it keeps running after the last client left (counted
    from the end of the log when the log kept it running longer).
    """

    keep_while_logging: bool = False
    grace_minutes: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.keep_while_logging, bool):
            raise ValueError(f"keep_while_logging must be true or false, got {self.keep_while_logging!r}")
        g = self.grace_minutes
        if isinstance(g, bool) or not isinstance(g, (int, float)) or not math.isfinite(g):
            raise ValueError(f"grace_minutes must be a number of minutes, got {g!r}")
        if not 0.0 <= g <= MAX_GRACE_MINUTES:
            raise ValueError(f"grace_minutes must be 0..{MAX_GRACE_MINUTES:g}, got {g:g}")


def unattended_action(policy: UnattendedPolicy, *, active: bool, logging: bool,
                      seconds_unattended: float, seconds_since_log: float | None = None) -> Action:
    """"keep" or "pause" for a session nobody is attached to.

    seconds_unattended: since the last client left.  seconds_since_log: since a log
    ended while unattended (None: none did); the grace counts from the later of the
    two events when the log was what kept the session running.
    """
    if not active:
        return "keep"
    if logging and policy.keep_while_logging:
        return "keep"
    idle = seconds_unattended
    if policy.keep_while_logging and seconds_since_log is not None:
        idle = min(idle, seconds_since_log)
    return "keep" if idle < policy.grace_minutes * 60.0 else "pause"


def _minutes(m: float) -> str:
    return "1 minute" if m == 1 else f"{m:g} minutes"


def describe(policy: UnattendedPolicy, *, active: bool) -> str:
    """The line shown when a client detaches (and by `quadtank lab`)."""
    if not active:
        return "Unattended, a Simul session keeps running until it is stopped."
    then = "then pauses with the pumps at 0."
    if policy.keep_while_logging:
        if policy.grace_minutes == 0:
            return ("Unattended, an Active session keeps running while its log is being written, "
                    f"{then}")
        return ("Unattended, an Active session keeps running while its log is being written and for "
                f"{_minutes(policy.grace_minutes)} after the last client left (or the log ended), {then}")
    if policy.grace_minutes == 0:
        return "Unattended, an Active session pauses with the pumps at 0 as soon as the last client leaves."
    return (f"Unattended, an Active session keeps running for {_minutes(policy.grace_minutes)} after "
            f"the last client left, logging or not, {then}")
