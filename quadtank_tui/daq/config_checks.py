"""Checking a DAQ configuration file's values, each refusal naming the file, the
line and the dotted key: what the Modbus map (daq/config.py) and the IST rig's
file (daq/ist/config.py) share.  The rules of each kind of file stay with it;
here are the error, the reader's error factory and the checks of one value."""

from __future__ import annotations

from typing import Any, Mapping, NoReturn

from quadtank_tui.core.ranges import is_finite_number

#: Default plausible range: this fraction of the tank height below 0 cm and above
#: the top (-2..22 cm for 20 cm tanks), room for a sensor's offset and noise.
PLAUSIBLE_MARGIN = 0.1


class DaqConfigError(ValueError):
    """A DAQ configuration refused; the message names the file, line and key."""

    def __init__(self, file: str, reason: str, *, key: str | None = None, line: int | None = None) -> None:
        where = file if line is None else f"{file}:{line}"
        what = f"{where}: {key}: {reason}" if key else f"{where}: {reason}"
        super().__init__(what)
        self.file, self.key, self.line, self.reason = file, key, line, reason


def config_error(name: str, message: str, line: int | None) -> DaqConfigError:
    """The error of a file that cannot be read or parsed (what files.yamltext's
    read_text and parse_yaml raise for a DAQ file)."""
    return DaqConfigError(name, message, line=line)


def show(value: Any) -> str:
    """A value as a message quotes it: its repr, cut at 40 characters."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


class Validator:
    """Checks of the values of one file (`name`, its keys' lines `lines`): each
    returns the value checked or raises DaqConfigError at the key's line (or its
    nearest parent's)."""

    def __init__(self, name: str, lines: Mapping[str, int]) -> None:
        self.name = name
        self.lines = lines

    def fail(self, key: str, reason: str) -> NoReturn:
        line = self.lines.get(key)
        probe = key
        while line is None and "." in probe:
            probe = probe.rsplit(".", 1)[0]
            line = self.lines.get(probe)
        raise DaqConfigError(self.name, reason, key=key, line=line)

    def mapping(self, key: str, value: Any, allowed: tuple[str, ...] | None = None) -> dict[str, Any]:
        if not isinstance(value, dict):
            self.fail(key, f"must be a mapping, got {show(value)}")
        for k in value:
            if not isinstance(k, str):
                self.fail(key, f"keys must be names, got {k!r}")
            if allowed is not None and k not in allowed:
                self.fail(f"{key}.{k}" if key else k, f"unknown key; expected one of {', '.join(allowed)}")
        return value

    def require(self, m: Mapping[str, Any], key: str, sub: str) -> Any:
        if sub not in m:
            self.fail(f"{key}.{sub}" if key else sub, "missing")
        return m[sub]

    def number(self, key: str, value: Any, lo: float | None = None, hi: float | None = None,
               *, lo_open: bool = False) -> float:
        if not is_finite_number(value):
            self.fail(key, f"must be a number, got {show(value)}")
        x = float(value)
        if lo is not None and (x <= lo if lo_open else x < lo):
            self.fail(key, f"must be {'>' if lo_open else '>='} {lo:g}, got {x:g}")
        if hi is not None and x > hi:
            self.fail(key, f"must be <= {hi:g}, got {x:g}")
        return x

    def integer(self, key: str, value: Any, lo: int, hi: int) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(key, f"must be a whole number, got {show(value)}")
        if not lo <= value <= hi:
            self.fail(key, f"must be in {lo}..{hi}, got {value}")
        return int(value)

    def choice(self, key: str, value: Any, options: tuple[str, ...]) -> str:
        if value not in options:
            self.fail(key, f"must be one of {', '.join(options)}, got {show(value)}")
        return str(value)

    def limits(self, key: str, value: Any, unit: str = "volts", bound: float = 10.5) -> tuple[float, float]:
        """[low, high], each within +-bound, low below high."""
        if not isinstance(value, list) or len(value) != 2:
            self.fail(key, f"must be [low, high] in {unit}, got {show(value)}")
        lo = self.number(f"{key}.0", value[0], -bound, bound)
        hi = self.number(f"{key}.1", value[1], -bound, bound)
        if not lo < hi:
            self.fail(key, f"low ({lo:g}) must be below high ({hi:g})")
        return (lo, hi)

    def plausible(self, m: Mapping[str, Any], tanks: tuple[str, ...],
                  unit: str) -> tuple[float, dict[str, tuple[float, float]]]:
        """`plausible:` - the default margin and the tanks' own ranges (in `unit`)."""
        margin = self.number("plausible.margin", m.get("margin", PLAUSIBLE_MARGIN), 0.0, 1.0)
        ranges = {tank: self.limits(f"plausible.{tank}", m[tank], unit, 1000.0) for tank in tanks if tank in m}
        return margin, ranges
