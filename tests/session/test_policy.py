"""The unattended policy: a table of every case the session process meets."""

from __future__ import annotations

import pytest

from quadtank_tui.session.policy import UnattendedPolicy, describe, unattended_action

DEFAULT = UnattendedPolicy(keep_while_logging=True, grace_minutes=10)  # docs/sessions.md's lab file example
STRICT = UnattendedPolicy(keep_while_logging=False, grace_minutes=0)
GRACE_ONLY = UnattendedPolicy(keep_while_logging=False, grace_minutes=5)

# policy, active, logging, s since the last client left, s since the log ended, expected
CASES = [
    (DEFAULT, False, False, 10**6, None, "keep"),    # Simul: always
    (STRICT, False, True, 10**6, None, "keep"),
    (STRICT, False, False, 0.0, None, "keep"),
    (DEFAULT, True, True, 10**6, None, "keep"),      # Active, logging: kept however long
    (DEFAULT, True, False, 0.0, None, "keep"),       # just left
    (DEFAULT, True, False, 599.9, None, "keep"),     # within the 10 minutes
    (DEFAULT, True, False, 600.0, None, "pause"),    # 10 minutes exactly: pause
    (DEFAULT, True, False, 3600.0, 599.0, "keep"),   # log ended 599 s ago: grace from then
    (DEFAULT, True, False, 3600.0, 600.0, "pause"),
    (DEFAULT, True, False, 30.0, 3000.0, "keep"),    # left after the log ended: from the leaving
    (STRICT, True, True, 0.0, None, "pause"),        # no keeping at all
    (STRICT, True, False, 0.0, None, "pause"),
    (GRACE_ONLY, True, True, 299.0, None, "keep"),   # logging does not keep it ...
    (GRACE_ONLY, True, True, 300.0, None, "pause"),
    (GRACE_ONLY, True, False, 3600.0, 10.0, "pause"),  # ... nor does a log that just ended
    (UnattendedPolicy(True, 0), True, True, 10**6, None, "keep"),
    (UnattendedPolicy(True, 0), True, False, 3600.0, 0.0, "pause"),
]


@pytest.mark.parametrize("policy,active,logging,unattended,since_log,expected", CASES)
def test_unattended_action(policy: UnattendedPolicy, active: bool, logging: bool, unattended: float,
                           since_log: float | None, expected: str) -> None:
    assert unattended_action(policy, active=active, logging=logging, seconds_unattended=unattended,
                             seconds_since_log=since_log) == expected


def test_without_a_policy_an_unattended_active_session_pauses_at_once() -> None:
    assert UnattendedPolicy() == STRICT
    assert unattended_action(UnattendedPolicy(), active=True, logging=True, seconds_unattended=0.0) == "pause"
    assert describe(UnattendedPolicy(), active=True) == (
        "Unattended, an Active session pauses with the pumps at 0 as soon as the last client leaves.")


def test_describe_says_what_the_table_does() -> None:
    assert describe(DEFAULT, active=True) == (
        "Unattended, an Active session keeps running while its log is being written and for 10 minutes "
        "after the last client left (or the log ended), then pauses with the pumps at 0.")
    assert describe(STRICT, active=True) == (
        "Unattended, an Active session pauses with the pumps at 0 as soon as the last client leaves.")
    assert describe(UnattendedPolicy(False, 1), active=True) == (
        "Unattended, an Active session keeps running for 1 minute after the last client left, logging "
        "or not, then pauses with the pumps at 0.")
    assert describe(UnattendedPolicy(True, 0), active=True) == (
        "Unattended, an Active session keeps running while its log is being written, then pauses with "
        "the pumps at 0.")
    assert describe(STRICT, active=False) == "Unattended, a Simul session keeps running until it is stopped."


@pytest.mark.parametrize("grace", [-1, float("nan"), float("inf"), 24 * 60 + 1, True, "10"])
def test_bad_grace_refused(grace: object) -> None:
    with pytest.raises(ValueError, match="grace_minutes"):
        UnattendedPolicy(grace_minutes=grace)  # type: ignore[arg-type]


def test_keep_must_be_a_bool() -> None:
    with pytest.raises(ValueError, match="keep_while_logging"):
        UnattendedPolicy(keep_while_logging="yes")  # type: ignore[arg-type]
