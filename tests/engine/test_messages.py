"""The engine pipe's messages: typed values both ends match on (issue 16)."""

from __future__ import annotations

import dataclasses
import pickle

import pytest

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.engine.commands import CommandResult, SetParams, SetState
from quadtank_tui.engine.messages import (
    Failed, MessageError, Ready, Result, Start, Stop, Stopped, Submit, from_loop, to_loop,
)

DOWN = [Start(), Submit(7, SetParams({"CONTROLLER ONE.K": 2.5})), Stop()]
UP = [Ready(PRESET), Failed("ValueError: bad"), Result(7, CommandResult(False, "refused", ("w",))),
      Stopped(), Stopped("RuntimeError: boom")]


@pytest.mark.parametrize("message", DOWN + UP, ids=lambda m: type(m).__name__)
def test_every_message_crosses_the_pipe_whole_and_is_frozen(message: object) -> None:
    copy = pickle.loads(pickle.dumps(message, protocol=5))
    assert copy == message and type(copy) is type(message)
    fields = dataclasses.fields(message)  # type: ignore[arg-type]
    if fields:
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(message, fields[0].name, None)


def test_each_end_takes_only_its_own_direction() -> None:
    for m in DOWN:
        assert to_loop(m) is m
        with pytest.raises(MessageError, match=f"not a message from the loop: {type(m).__name__}"):
            from_loop(m)
    for m in UP:
        assert from_loop(m) is m
        with pytest.raises(MessageError):
            to_loop(m)
    with pytest.raises(MessageError, match="not a message for the loop: tuple"):
        to_loop(("command", 1, SetState("Run")))  # the old untyped form
