"""`.par`: the thesis's fragments load, the complete format round-trips exactly,
broken files are refused as a whole with file/line/key, saves are atomic."""

from __future__ import annotations

import os
from datetime import datetime
from pathlib import Path

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from quadtank_tui.core.parameters import KEYS, PRESET, Kind, KeySpec, Parameters
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.files import atomic
from quadtank_tui.files.names import LOG_VARIABLES, PLOT_TYPES
from quadtank_tui.files.par import ParFileError, format_number, format_par, parse_par, read_par, write_par
from quadtank_tui.files.shipped import SHIPPED_STAMP, shipped_settings

GOLDEN = Path(__file__).parent / "golden"
PARAMS = Path(__file__).parents[2] / "params"
STAMP = datetime(1997, 8, 5, 14, 1, 47)


# --- the thesis's samples ------------------------------------------------------------------

def test_thesis_fragment_with_header_loads() -> None:
    read = read_par(GOLDEN / "thesis_fragment1.par")
    p = read.params
    assert read.warnings == ()
    assert p.tsamp_ms == 100.0
    ref = p.references[0]
    assert (ref.mean, ref.period, ref.amplitude) == (0.3, 6.0, 0.15)
    assert (p.logging.points, p.logging.log_file) == (120, "data")
    assert p.modified_keys(PRESET) == {"REFERENCE ONE.Period", "REFERENCE ONE.Amplitude", "LOGGING.Points"}


def test_thesis_simulation_fragment_loads() -> None:
    p = read_par(GOLDEN / "thesis_fragment2.par").params
    assert p.simulation.diameters[0] == 5.93
    assert (p.simulation.op_points[0], p.simulation.valves) == (0.62, (0.7, 0.6))
    assert p.modified_keys(PRESET) == {"SIMULATION.Diameter1"}


def test_thesis_controller_fragment_loads() -> None:
    p = read_par(GOLDEN / "thesis_fragment3.par").params
    c = p.controllers[0]
    assert (c.pid.K, c.pid.Ti, c.pid.Td, c.pid.Tr) == (3.0, 30.0, 0.0, 1.0)
    assert (c.general.r[0], c.general.s[0]) == (1.0, 1.0)
    assert p.modified_keys(PRESET) == {"CONTROLLER ONE.r1", "CONTROLLER ONE.s0"}


def test_the_three_fragments_together() -> None:
    text = "".join((GOLDEN / f"thesis_fragment{i}.par").read_text() + "\n" for i in (1, 2, 3))
    p = parse_par(text).params
    assert p.modified_keys(PRESET) == {
        "REFERENCE ONE.Period", "REFERENCE ONE.Amplitude", "LOGGING.Points",
        "SIMULATION.Diameter1", "CONTROLLER ONE.r1", "CONTROLLER ONE.s0",
    }


def test_shipped_files_are_what_the_writer_produces() -> None:
    for name, params in shipped_settings().items():
        on_disk = (PARAMS / f"{name}.par").read_text()
        assert on_disk == format_par(params, SHIPPED_STAMP), name
        assert read_par(PARAMS / f"{name}.par").params == params


# --- the written format ----------------------------------------------------------------------

def test_format_starts_like_the_original() -> None:
    text = format_par(PRESET, STAMP)
    assert text.startswith(
        "% TANK PAR-file\n% Created on: Aug 05 14:01:47 1997\n\nSAMPLING TIME\nTSamp 100.0000\n\n"
        "REFERENCE ONE\nWave Square\nMean 0.300000\nPeriod 60.000000\nAmplitude 0.050000\nOn 0\nSeed 1\n\n"
    )
    assert "\nCONTROLLER ONE\nK 3.000000\nTi 30.000000\nTd 0.000000\nTr 1.000000\nN 10.000000\n" in text
    assert "\nSIMULATION\nDiameter1 5.970821\nOpPoint1 0.620000\nTimeConst1 62.703390\n" in text
    assert text.endswith("\nLOGGING\nPoints 5000\nLogFile data\nVariables y1 y2 u1 u2\n\n"
                         "PLOTS\nUpper u1 u2\nLower y1 y2 ref1 ref2\n\n"
                         "STATE FEEDBACK\nTs 60.000000\nPoles zeros\nL3 1.000000\nSmart 1\n"
                         "LevelMargin 2.000000\nLevel1 12.400000\nLevel2 12.700000\n\n"
                         "MPC\nHorizon 30\nStep 0.000000\nControlHorizon 0\nOutputWeight 1.000000\nInputWeight 0.010000\n"
                         "RateWeight 0.000000\nRateLimit 0.000000\nLevelMargin 1.000000\nPreview 1\n"
                         "Disturbance input\nMeasured all\nSlackWeight 1000.000000\n")


@pytest.mark.parametrize(
    "x, text",
    [(3.0, "3.000000"), (0.0675, "0.067500"), (-0.12, "-0.120000"), (1e-7, "0.0000001"),
     (1 / 3, "0.3333333333333333"), (123456.1234567, "123456.1234567"), (-0.12 / 220, "-0.0005454545454545455")],
)
def test_numbers_are_percent_f_unless_that_would_lose_digits(x: float, text: str) -> None:
    assert format_number(x) == text
    assert float(text) == x


def _value_strategy(k: KeySpec) -> st.SearchStrategy[object]:
    ranges = {
        "TSamp": (50, 10_000), "Mean": (-1, 2), "Period": (20, 1e4), "Amplitude": (0, 1), "K": (-1e3, 1e3),
        "Ti": (1e-3, 1e6), "Td": (0, 1e6), "Tr": (1e-3, 1e6), "N": (1e-3, 1e3), "a": (0, 1), "b": (0, 1),
        "Valve1": (0, 1), "Valve2": (0, 1), "Pump1": (1e-3, 100), "Pump2": (1e-3, 100), "Sensor": (0.05, 10),
        "Diameter": (0.5, 100), "OpPoint": (1e-4, 1), "TimeConst": (1, 1e5),
    }
    if k.kind is Kind.NUMBER:
        lo, hi = ranges.get(k.key.rstrip("1234"), ranges.get(k.key, (-1e9, 1e9)))
        exact = st.floats(lo, hi, allow_nan=False, allow_infinity=False)
        return st.one_of(exact, exact.map(lambda x: round(x, 3)))
    if k.kind is Kind.INTEGER:
        return {"Degree": st.integers(0, 4), "Points": st.integers(1, 100_000)}.get(k.key, st.integers(0, 2**31 - 1))
    if k.kind is Kind.FLAG:
        return st.booleans()
    if k.kind is Kind.CHOICE:
        return st.sampled_from(k.choices)
    if k.section == "PLOTS":
        return st.sampled_from(PLOT_TYPES)
    if k.kind is Kind.NAME:
        return st.from_regex(r"[A-Za-z0-9_][A-Za-z0-9_\-]{0,20}", fullmatch=True)
    return st.lists(st.sampled_from(LOG_VARIABLES), min_size=1, max_size=9, unique=True)


#: Each key's strategy, made once: a strategy made anew at every draw was validated
#: anew (the name regex's character set alone was 55 % of the round-trip test's time).
VALUE_STRATEGIES = {k.name: _value_strategy(k) for k in KEYS}


@st.composite
def parameter_sets(draw: st.DrawFn) -> Parameters:
    chosen = draw(st.lists(st.sampled_from(KEYS), max_size=len(KEYS), unique=True))
    changes = {k.name: draw(VALUE_STRATEGIES[k.name]) for k in chosen}
    try:
        return PRESET.with_values(changes)
    except ParameterError:
        assume(False)
        raise


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(parameter_sets())
def test_round_trip_is_exact(p: Parameters) -> None:
    text = format_par(p, STAMP)
    back = parse_par(text, name="rt.par")
    assert back.warnings == ()
    assert back.params == p
    assert format_par(back.params, STAMP) == text


def test_round_trip_through_a_file(tmp_path: Path) -> None:
    p = PRESET.with_values({"SIMULATION.Diameter1": 5.93, "CONTROLLER ONE.s1": 1 / 3, "SAMPLING TIME.TSamp": 123.45678})
    write_par(tmp_path / "x.par", p, created=STAMP)
    assert read_par(tmp_path / "x.par").params == p
    assert "TSamp 123.45678\n" in (tmp_path / "x.par").read_text()


# --- tolerant reading ---------------------------------------------------------------------------

def test_any_order_crlf_tabs_and_blank_lines() -> None:
    text = ("% TANK PAR-file\r\n\r\nSIMULATION\r\nValve2\t0.55\r\nValve1 0.65   \r\n\r\n"
            "CONTROLLER FOUR\r\nTi 45\r\nK 2.5\r\n\r\n\r\nSAMPLING TIME\r\nTSamp 200\r\n")
    p = parse_par(text).params
    assert p.simulation.valves == (0.65, 0.55)
    assert (p.controllers[3].pid.K, p.controllers[3].pid.Ti) == (2.5, 45.0)
    assert p.tsamp_ms == 200.0


def test_keys_match_whatever_their_case() -> None:
    p = parse_par("SAMPLING TIME\ntsamp 250\n\nCONTROLLER ONE\nk 2.0\nTI 20\n").params
    assert (p.tsamp_ms, p.controllers[0].pid.K, p.controllers[0].pid.Ti) == (250.0, 2.0, 20.0)
    with pytest.raises(ParFileError, match="line 3: CONTROLLER ONE.K: duplicate key \\(first set on line 2\\)"):
        parse_par("CONTROLLER ONE\nK 2.0\nk 3.0\n")
    assert len({(k.section, k.key.lower()) for k in KEYS}) == len(KEYS)


def test_numbers_in_percent_f_form_for_whole_and_flag_values() -> None:
    p = parse_par("LOGGING\nPoints 600.000000\n\nCONTROLLER ONE\nI 0.000000\nD 1.000000\nDegree 2.000000\n").params
    assert p.logging.points == 600
    assert (p.controllers[0].pid.integral, p.controllers[0].pid.derivative) == (False, True)
    assert p.controllers[0].general.degree == 2


def test_unknown_sections_and_keys_are_kept_and_reported() -> None:
    text = "SIMULATION\nValve1 0.65\nFlowMeter 3.2\n\nWINDOWS\nMainX 10\nMainY 20\n"
    read = parse_par(text, name="old.par")
    assert read.params.simulation.valves[0] == 0.65
    assert read.warnings == (
        "old.par, line 3: unknown key 'FlowMeter' in SIMULATION (kept, not used)",
        "old.par, line 5: unknown section 'WINDOWS' (kept, not used)",
    )
    out = format_par(read.params, STAMP)
    assert "Sensor 0.500000\nFlowMeter 3.2\n\nLOGGING\n" in out
    assert out.endswith("\nSlackWeight 1000.000000\n\nWINDOWS\nMainX 10\nMainY 20\n")
    assert parse_par(out).params == read.params


def test_missing_values_take_the_given_base() -> None:
    base = PRESET.with_value("CONTROLLER ONE.K", 9.0)
    assert parse_par("SIMULATION\nValve1 0.5\n", base=base).params.get("CONTROLLER ONE.K") == 9.0


# --- broken files ------------------------------------------------------------------------------

_FULL = format_par(PRESET, STAMP)
_CUT = _FULL.index("TimeConst1") + len("TimeConst1")

BROKEN: list[tuple[str, bytes, int | None, str | None, str]] = [
    ("truncated mid-entry", _FULL[:_CUT].encode(), _FULL[:_CUT].count("\n") + 1, "TimeConst1",
     "malformed line: expected 'Key value'"),
    ("truncated to the header", b"% TANK PAR-file\n% Created on: Aug 05 14:0", 2, None,
     "no section found: not a parameter file (empty or truncated?)"),
    ("empty", b"", 1, None, "no section found: not a parameter file (empty or truncated?)"),
    ("binary junk with NUL", b"SIMULATION\nValve1 0.5\n\x1a\n\x00\x00\x00\rIHDR", 4, None,
     "binary data (NUL byte): not a parameter file"),
    ("binary junk, undecodable", b"SIMULATION\nValve1 0.5\nValve2 \xff\xfe\xfd\n", 3, None,
     "not a text file (undecodable byte)"),
    ("control characters", b"SIMULATION\nValve1 0.5\x07\x1b\n", 2, None,
     "binary or control characters: not a parameter file"),
    ("NaN", b"CONTROLLER ONE\nK nan\n", 2, "CONTROLLER ONE.K", "not a number: 'nan'"),
    ("infinity", b"CONTROLLER ONE\nK inf\n", 2, "CONTROLLER ONE.K", "not a number: 'inf'"),
    ("non-number", b"REFERENCE ONE\nMean 0.3\nPeriod six\n", 3, "REFERENCE ONE.Period", "not a number: 'six'"),
    ("huge number overflows", b"CONTROLLER TWO\ns0 1e999\n", 2, "CONTROLLER TWO.s0", "number too large: '1e999'"),
    ("huge number out of bounds", b"CONTROLLER TWO\ns0 1e300\n", 2, "CONTROLLER TWO.s0",
     "must be within +-1e+09, got 1e+300"),
    ("huge digit string", b"LOGGING\nPoints " + b"9" * 5000 + b"\n", 2, "LOGGING.Points",
     "number too large: '" + "9" * 40 + "'"),
    ("valve out of range", b"SIMULATION\nValve1 0.7\nValve2 1.6\n", 3, "SIMULATION.Valve2", "must be <= 1, got 1.6"),
    ("sampling time under 50 ms", b"SAMPLING TIME\nTSamp 20.0000\n", 2, "SAMPLING TIME.TSamp",
     "must be >= 50, got 20"),
    ("period too short for TSamp", b"SAMPLING TIME\nTSamp 5000.0000\n\nREFERENCE ONE\nPeriod 6.000000\n", 5,
     "REFERENCE ONE.Period", "6 s is shorter than twice the sampling time (5 s): the shortest allowed is 10 s"),
    ("binary junk, NUL after a bad byte", b"SIMULATION\n\x89PNG\r\n\x1a\n\x00\x00", 2, None,
     "not a text file (undecodable byte)"),
    ("duplicate key", b"CONTROLLER ONE\nK 3.0\nTi 30\nK 2.0\n", 4, "CONTROLLER ONE.K",
     "duplicate key (first set on line 2)"),
    ("duplicate key across repeated section", b"SIMULATION\nValve1 0.5\n\nSIMULATION\nValve1 0.6\n", 5,
     "SIMULATION.Valve1", "duplicate key (first set on line 2)"),
    ("key without section", b"% TANK PAR-file\n\nTSamp 100\n", 3, "TSamp",
     "entry outside any section (a section name in capitals must come first)"),
    ("bad choice", b"REFERENCE ONE\nWave Triangle\n", 2, "REFERENCE ONE.Wave",
     "must be one of Square, Sine, PRBS; got 'Triangle'"),
    ("bad flag", b"CONTROLLER ONE\nI 2\n", 2, "CONTROLLER ONE.I", "must be 0 or 1, got 2.0"),
    ("path as log name", b"LOGGING\nLogFile ../../etc/x\n", 2, "LOGGING.LogFile",
     "must be a plain file name (letters, digits, _ - .; no folders), got '../../etc/x'"),
    ("a log file", b"% TANK LOG-file\n% Logged variables: y1   TSamp: 1s\n\n0.5\n", 1, None,
     "this is a .log data file, not a .par parameter file"),
]


@pytest.mark.parametrize("what, data, line, key, reason", BROKEN, ids=[b[0] for b in BROKEN])
def test_broken_files_are_refused_whole(tmp_path: Path, what: str, data: bytes, line: int | None,
                                        key: str | None, reason: str) -> None:
    path = tmp_path / "broken.par"
    path.write_bytes(data)
    current = PRESET.with_value("CONTROLLER ONE.K", 2.0)
    snapshot = format_par(current, STAMP)
    with pytest.raises(ParFileError) as info:
        current = read_par(path, base=current).params
    err = info.value
    assert err.file == str(path)
    if line is not None:
        assert err.line == line
    assert err.key == key
    if reason:
        assert err.reason == reason
        where = f"{path}, line {line}" if line is not None else str(path)
        assert str(err) == f"{where}: {key + ': ' if key else ''}{reason}"
    assert format_par(current, STAMP) == snapshot  # the parameters in use are untouched


def test_a_sampling_time_too_long_for_the_period_points_at_tsamp() -> None:
    """The file sets TSamp only; the period it conflicts with comes from the base."""
    base = PRESET.with_value("REFERENCE ONE.Period", 6.0)
    text = "SIMULATION\nValve1 0.5\n\nSAMPLING TIME\nTSamp 5000\n"
    with pytest.raises(ParFileError) as info:
        parse_par(text, name="t.par", base=base)
    assert (info.value.line, info.value.key) == (5, "REFERENCE ONE.Period")
    assert str(info.value) == "t.par, line 5: REFERENCE ONE.Period: 6 s is shorter than twice the sampling time (5 s): the shortest allowed is 10 s"


def test_missing_and_oversized_files(tmp_path: Path) -> None:
    with pytest.raises(ParFileError, match="nope.par: no such file"):
        read_par(tmp_path / "nope.par")
    big = tmp_path / "big.par"
    big.write_bytes(b"SIMULATION\n" + b"% padding\n" * 200_000)
    with pytest.raises(ParFileError, match="larger than 1000000 bytes"):
        read_par(big)


# --- atomic save ------------------------------------------------------------------------------------

def test_save_interrupted_before_rename_leaves_old_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "lab.par"
    write_par(path, PRESET, created=STAMP)
    before = path.read_bytes()

    def crash(src: str, dst: str) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(atomic.os, "replace", crash)
    with pytest.raises(OSError, match="No space left"):
        write_par(path, PRESET.with_value("SIMULATION.Valve1", 0.4), created=STAMP)
    assert path.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["lab.par"]  # no temporary file left behind


def test_a_failed_save_names_the_file_not_the_temporary_one(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "mine.par"

    def denied(src: str, dst: str) -> None:
        raise PermissionError(13, "Permission denied", src, dst)

    monkeypatch.setattr(atomic.os, "replace", denied)
    with pytest.raises(PermissionError) as info:
        write_par(path, PRESET, created=STAMP)
    assert str(info.value) == f"[Errno 13] Permission denied: '{path}'"
    monkeypatch.setattr(atomic.tempfile, "mkstemp", lambda **kw: denied(kw["dir"] / f"{kw['prefix']}x{kw['suffix']}", ""))
    with pytest.raises(PermissionError) as info:
        write_par(path, PRESET, created=STAMP)
    assert ".tmp" not in str(info.value) and str(path) in str(info.value)
    assert os.listdir(tmp_path) == []


def test_save_replaces_content(tmp_path: Path) -> None:
    path = tmp_path / "lab.par"
    write_par(path, PRESET, created=STAMP)
    write_par(path, PRESET.with_value("SIMULATION.Valve1", 0.4), created=STAMP)
    assert read_par(path).params.simulation.valves[0] == 0.4
    assert sorted(os.listdir(tmp_path)) == ["lab.par"]
