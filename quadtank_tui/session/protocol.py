"""The messages between a session process and its clients, as JSON lines.

A peer on the session's socket is another process, possibly another user's: it is
never trusted with pickle (which runs code).  Every message is a frozen dataclass;
on the wire it is one line of JSON whose objects carry a type tag ``"@"``.  Only
the types named here are ever built on decoding: the messages, the engine's
commands, the snapshot and everything a snapshot holds (found by walking their
fields' annotations), with their own validation (``__post_init__``) run as usual.

Values: None, bool, int, float (inf and nan included, as Python's json writes
them), str and lists are plain JSON; tuples, mappings, enums, complex numbers,
paths and float arrays (base64 of little-endian float64: exact and compact, the
trends' whole ring buffer is 2.6 MB) are tagged objects.
"""

from __future__ import annotations

import base64
import dataclasses
import enum
import importlib
import json
import sys
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Union

import numpy as np

from quadtank_tui.core.parameters import Parameters
from quadtank_tui.engine import commands as engine_commands
from quadtank_tui.engine.commands import Command, CommandResult
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.session.info import SessionInfo

#: Longest line a session reads from a client once its Hello is accepted (a command
#: is a few hundred bytes; a SetParams of a whole .par a few kilobytes).
MAX_CLIENT_LINE = 1 << 18
#: Longest line a session reads from a connection that has not said Hello (about
#: 60 bytes): anyone on the machine may connect, so what an unknown peer may make
#: the session hold is small.
MAX_HELLO_LINE = 1 << 12
#: Deepest nesting of lists and objects in a line (a snapshot's is about 8).
MAX_DEPTH = 32
#: Longest line a client reads from a session (the whole history on attach).
MAX_SESSION_LINE = 1 << 28

Role = Literal["operator", "observer", "control"]


class ProtocolError(ValueError):
    """A line that is not a message of this protocol (the peer is dropped)."""


# --- the messages ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Hello:
    """The first line a client sends: what it wants to be.  `take_over`: an
    administrator takes the operator's place."""

    role: Role
    client: str = ""
    take_over: bool = False

    def __post_init__(self) -> None:
        # The session acts on these before anything else: a peer's wrong types are refused here.
        if self.role not in ("operator", "observer", "control"):
            raise ValueError(f"role must be operator, observer or control, not {self.role!r:.40}")
        if not isinstance(self.client, str) or len(self.client) > 200:
            raise ValueError("client must be a short string")
        if not isinstance(self.take_over, bool):
            raise ValueError("take_over must be true or false")


@dataclass(frozen=True)
class Submit:
    """Apply `command` between samples and answer with a :class:`Result` of the same id."""

    id: int
    command: Command


@dataclass(frozen=True)
class Result:
    """What became of the :class:`Submit` with this `id`."""

    id: int
    result: CommandResult


@dataclass(frozen=True)
class StopSession:
    """Stop the session: pumps at 0, logging stopped (the rows kept), process gone."""


@dataclass(frozen=True)
class Welcome:
    """Everything a client needs to be live at once: the snapshot, the defaults, the
    folders, and the whole ring buffer in the `parts` HistoryPart lines that follow
    it before anything else."""

    info: SessionInfo
    role: Role
    snapshot: Snapshot
    defaults: Parameters
    capacity: int
    params_dir: str
    logs_dir: str
    controller: str
    #: What the session does when its operator leaves, in Simul and in Active
    #: (session.policy.describe).
    policy_simul: str = ""
    policy_active: str = ""
    parts: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.parts, int) or isinstance(self.parts, bool) or not 0 <= self.parts <= 1 << 20:
            raise ValueError(f"parts must be a count of lines, not {self.parts!r:.40}")


@dataclass(frozen=True)
class HistoryPart:
    """Rows of the ring buffer (engine.handle.SIGNALS order), oldest first, after a
    Welcome: the session encodes one part per event-loop turn (the whole 36000
    rows in one line held its sampling 100-200 ms)."""

    rows: np.ndarray


@dataclass(frozen=True)
class Refused:
    """The Hello (or a StopSession) was refused; the session closes the connection."""

    reason: str


@dataclass(frozen=True)
class Update:
    """Samples since the last update (rows) and the newest snapshot.  `cleared`: the
    history was cleared (Reset) before these rows.  `snapshot.params` is None when
    the parameters are those of the previous update (they change far less often)."""

    snapshot: Snapshot
    rows: np.ndarray
    cleared: bool = False


@dataclass(frozen=True)
class Roster:
    """Who controls the session and how many are attached (sent when it changes)."""

    controller: str
    clients: int
    role: Role = "observer"    # this client's role now (an operator taken over becomes an observer)


@dataclass(frozen=True)
class Ended:
    """The session is stopping (pumps at 0, log kept) and says why."""

    reason: str


@dataclass(frozen=True)
class Dropped:
    """The session drops this client (it flooded, sent a line that is not a message,
    fell too far behind) and says why, as its last line to it: the session runs on
    and keeps driving its process, so the client must not take the closed
    connection for the session's death (and must not put the pumps at 0).  A client
    older than this message takes the line for a protocol error, i.e. the session's
    death, as it did every drop before."""

    reason: str


Message = Union[Hello, Submit, StopSession, Welcome, HistoryPart, Refused, Update, Result, Roster, Ended, Dropped]
MESSAGES: tuple[type, ...] = (SessionInfo, Hello, Submit, StopSession, Welcome, HistoryPart, Refused, Update,
                              Result, Roster, Ended, Dropped)
#: What a client may send.
CLIENT_MESSAGES: tuple[type, ...] = (Hello, Submit, StopSession)


# --- the types a line may build ----------------------------------------------------------------

#: Types whose annotations cannot be resolved without a heavy import (scipy): by name.
_LAZY = {"StateFeedbackInfo": ("quadtank_tui.core.controllers.statefb.quadtank", "StateFeedbackInfo")}


@dataclass
class _Registry:
    types: dict[str, type] = field(default_factory=dict)

    def add(self, tp: Any) -> None:
        origin = typing.get_origin(tp)
        if origin is not None:
            for arg in typing.get_args(tp):
                self.add(arg)
            return
        if not isinstance(tp, type) or tp.__name__ in self.types:
            return
        if dataclasses.is_dataclass(tp):
            self.types[tp.__name__] = tp
            module = vars(sys.modules[tp.__module__])
            for f in dataclasses.fields(tp):
                try:
                    hint = eval(f.type, module) if isinstance(f.type, str) else f.type  # noqa: S307 - our own annotations
                except NameError:
                    continue  # a TYPE_CHECKING import: registered lazily by name
                self.add(hint)
        elif issubclass(tp, enum.Enum):
            self.types[tp.__name__] = tp

    def get(self, name: str) -> type:
        tp = self.types.get(name)
        if tp is None and name in _LAZY:
            module, attr = _LAZY[name]
            tp = getattr(importlib.import_module(module), attr)
            self.types[name] = tp
        if tp is None:
            raise ProtocolError(f"unknown type {name!r}")
        return tp


def _build_registry() -> _Registry:
    reg = _Registry()
    for tp in (*MESSAGES, *typing.get_args(Command), CommandResult, Snapshot, Parameters):
        reg.add(tp)
    return reg


_REGISTRY = _build_registry()
_COMMANDS = frozenset(t.__name__ for t in typing.get_args(Command))
assert all(hasattr(engine_commands, n) for n in _COMMANDS)


# --- encoding ----------------------------------------------------------------------------------


def _enc(value: Any) -> Any:
    if value is None or isinstance(value, (bool, int, float, str)) and not isinstance(value, enum.Enum):
        return value
    if isinstance(value, enum.Enum):
        return {"@": "enum", "t": type(value).__name__, "v": _enc(value.value)}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        name = type(value).__name__
        if name not in _REGISTRY.types and name not in _LAZY:
            raise ProtocolError(f"{name} is not a message type")
        out: dict[str, Any] = {"@": name}
        for f in dataclasses.fields(value):
            out[f.name] = _enc(getattr(value, f.name))
        return out
    if isinstance(value, tuple):
        return {"@": "tuple", "v": [_enc(v) for v in value]}
    if isinstance(value, list):
        return [_enc(v) for v in value]
    if isinstance(value, typing.Mapping):
        return {"@": "map", "v": [[_enc(k), _enc(v)] for k, v in value.items()]}
    if isinstance(value, complex):
        return {"@": "complex", "v": [value.real, value.imag]}
    if isinstance(value, Path):
        return {"@": "path", "v": str(value)}
    if isinstance(value, np.ndarray):
        data = np.ascontiguousarray(value, dtype="<f8")
        return {"@": "array", "shape": list(data.shape), "b64": base64.b64encode(data.tobytes()).decode()}
    if isinstance(value, np.floating):
        return float(value)
    if isinstance(value, np.integer):
        return int(value)
    raise ProtocolError(f"cannot send a {type(value).__name__}")


def encode(message: Any) -> bytes:
    """One line (newline included)."""
    return json.dumps(_enc(message), separators=(",", ":")).encode() + b"\n"


def _array_line(rows: np.ndarray) -> bytes:
    """encode's form of an array, written out: json's pass over the base64 (which
    needs no escaping) was most of encoding a message that carries rows."""
    data = np.ascontiguousarray(rows, dtype="<f8")
    shape = ",".join(str(n) for n in data.shape).encode()
    return b'{"@":"array","shape":[%s],"b64":"%s"}' % (shape, base64.b64encode(data.tobytes()))


def encode_history_part(rows: np.ndarray) -> bytes:
    """encode(HistoryPart(rows)), byte for byte, at a quarter of the cost."""
    if np.ndim(rows) != 2:
        raise ProtocolError("a part of the history is a table of rows")
    return b'{"@":"HistoryPart","rows":%s}\n' % _array_line(rows)


def encode_update(update: Update) -> bytes:
    """encode(update), byte for byte, its rows written out: a session publishes one
    every PUBLISH_INTERVAL, at x1000 and 50 ms with 400 rows (39 KB), and json's
    generic pass over the rows would be half its encoding, on the sampling thread's
    time."""
    snapshot = json.dumps(_enc(update.snapshot), separators=(",", ":")).encode()
    return b'{"@":"Update","snapshot":%s,"rows":%s,"cleared":%s}\n' % (
        snapshot, _array_line(update.rows), b"true" if update.cleared else b"false")


# --- decoding ----------------------------------------------------------------------------------


def _dec(value: Any, depth: int = 0) -> Any:
    if depth > MAX_DEPTH:
        raise ProtocolError("nested too deeply")
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, list):
        return [_dec(v, depth + 1) for v in value]
    if not isinstance(value, dict):
        raise ProtocolError(f"unexpected {type(value).__name__}")
    tag = value.get("@")
    if tag == "tuple":
        return tuple(_dec(v, depth + 1) for v in _list(value, "v"))
    if tag == "map":
        pairs = _list(value, "v")
        if not all(isinstance(p, list) and len(p) == 2 for p in pairs):
            raise ProtocolError("a map holds [key, value] pairs")
        return {_dec(k, depth + 1): _dec(v, depth + 1) for k, v in pairs}
    if tag == "complex":
        re_im = _list(value, "v")
        if len(re_im) != 2 or not all(isinstance(x, (int, float)) for x in re_im):
            raise ProtocolError("a complex number is [re, im]")
        return complex(*re_im)
    if tag == "path":
        return Path(_str(value, "v"))
    if tag == "array":
        return _array(value)
    if tag == "enum":
        tp = _REGISTRY.get(_str(value, "t"))
        if not issubclass(tp, enum.Enum):
            raise ProtocolError(f"{tp.__name__} is not an enum")
        try:
            return tp(_dec(value.get("v"), depth + 1))
        except ValueError as exc:
            raise ProtocolError(str(exc)) from None
    if not isinstance(tag, str):
        raise ProtocolError("an object without a type tag")
    tp = _REGISTRY.get(tag)
    if not dataclasses.is_dataclass(tp):
        raise ProtocolError(f"{tag} is not a message type")
    names = {f.name for f in dataclasses.fields(tp) if f.init}
    extra = set(value) - names - {"@"}
    if extra:
        raise ProtocolError(f"{tag} has no field {sorted(extra)[0]!r}")
    kwargs = {k: _dec(v, depth + 1) for k, v in value.items() if k != "@"}
    try:
        return tp(**kwargs)
    except (TypeError, ValueError) as exc:  # ParameterError is a ValueError
        raise ProtocolError(f"bad {tag}: {exc}") from None


def _list(obj: dict[str, Any], key: str) -> list[Any]:
    v = obj.get(key)
    if not isinstance(v, list):
        raise ProtocolError(f"{obj.get('@')}: {key} must be a list")
    return v


def _str(obj: dict[str, Any], key: str) -> str:
    v = obj.get(key)
    if not isinstance(v, str):
        raise ProtocolError(f"{obj.get('@')}: {key} must be a string")
    return v


def _array(obj: dict[str, Any]) -> np.ndarray:
    shape = _list(obj, "shape")
    if not all(isinstance(n, int) and n >= 0 for n in shape) or len(shape) > 2:
        raise ProtocolError("an array's shape is one or two sizes")
    try:
        raw = base64.b64decode(_str(obj, "b64"), validate=True)
    except ValueError:
        raise ProtocolError("an array's data is not base64") from None
    count = int(np.prod(shape)) if shape else 1
    if len(raw) != 8 * count:
        raise ProtocolError(f"an array of shape {shape} needs {8 * count} bytes, got {len(raw)}")
    return np.frombuffer(raw, dtype="<f8").astype(float).reshape(shape)


def decode(line: bytes, allowed: tuple[type, ...] = MESSAGES) -> Any:
    """The message on `line`; ProtocolError if it is not one of `allowed`.

    Whatever a peer sends, nothing but ProtocolError comes out of here: JSON
    nested past the interpreter's recursion limit (the parser's RecursionError),
    past MAX_DEPTH (ours), and anything a type's own construction raises on a
    peer's values (an unhashable map key, a wrong type in a validation) are the
    peer's fault, not the session's."""
    try:
        obj = json.loads(line)
    except (ValueError, UnicodeDecodeError, RecursionError) as exc:
        raise ProtocolError(f"not JSON: {exc}") from None
    try:
        message = _dec(obj)
    except ProtocolError:
        raise
    except Exception as exc:  # noqa: BLE001 - a peer's values broke a constructor: refuse the line
        raise ProtocolError(f"not a message: {type(exc).__name__}: {exc}"[:300]) from None
    if not isinstance(message, allowed):
        raise ProtocolError(f"unexpected message {type(message).__name__}")
    if isinstance(message, Submit) and type(message.command).__name__ not in _COMMANDS:
        raise ProtocolError(f"{type(message.command).__name__} is not a command")
    return message


class LineReader:
    """Splits a byte stream into lines of at most `limit` bytes: what it holds for a
    peer is never more than `limit` (plus one read), however the bytes come."""

    def __init__(self, limit: int) -> None:
        self._buf = bytearray()
        self._scanned = 0   # no newline before this offset of _buf
        self.limit = limit

    @property
    def held(self) -> int:
        """Bytes of an unfinished line held."""
        return len(self._buf)

    def feed(self, data: bytes) -> list[bytes]:
        self._buf += data
        lines: list[bytes] = []
        while True:
            nl = self._buf.find(b"\n", self._scanned)
            if nl < 0:
                self._scanned = len(self._buf)
                if len(self._buf) > self.limit:
                    raise ProtocolError(f"a line longer than {self.limit} bytes")
                return lines
            if nl > self.limit:
                raise ProtocolError(f"a line longer than {self.limit} bytes")
            lines.append(bytes(self._buf[:nl]))
            del self._buf[:nl + 1]
            self._scanned = 0
