"""The one parameter model: preset values from the paper's table, access by
"SECTION.Key", validation that names the key, and the modified-value query."""

from __future__ import annotations

import math

import pytest

from quadtank_tui.core.parameters import (
    KEYS,
    NAMED_SETTINGS,
    PRESET,
    ControlMode,
    Family,
    Parameters,
    Structure,
    iter_keys,
    keys_of,
    spec,
)
from quadtank_tui.core.plants.johansson import P_MINUS, P_PLUS
from quadtank_tui.core.controllers.signals import Wave
from quadtank_tui.core.ranges import ParameterError


def test_preset_is_the_thesis_setting() -> None:
    p = PRESET
    assert p.tsamp_ms == 100.0 and p.tsamp == 0.1
    assert p.control.mode is ControlMode.MANUAL
    assert p.control.family is Family.PID and p.control.structure is Structure.DECENTRALIZED
    c11, c22 = p.controllers[0].pid, p.controllers[3].pid
    assert (c11.K, c11.Ti, c11.integral, c11.derivative) == (3.0, 30.0, True, False)
    assert (c22.K, c22.Ti) == (2.7, 40.0)
    assert p.controllers[1].pid.K == 0.0 and p.controllers[2].pid.K == 0.0
    assert [r.mean for r in p.references] == [0.30, 0.30]
    assert p.logging.points == 5000 and p.logging.log_file == "data"
    assert p.logging.variables == ("y1", "y2", "u1", "u2")
    assert (p.plots.upper, p.plots.lower) == ("u1 u2", "y1 y2 ref1 ref2")


def test_preset_simulation_section_rebuilds_the_paper_plant() -> None:
    sim = PRESET.simulation
    assert sim.diameters == (5.970821, 6.383076, 5.970821, 6.383076)
    assert sim.op_points == (0.62, 0.635, 0.09, 0.07)
    assert sim.time_constants == (62.70339, 90.335297, 23.890015, 29.992981)
    plant = PRESET.quadtank_constants()
    want = P_MINUS.params
    for name in ("A1", "A2", "A3", "A4", "a1", "a2", "a3", "a4"):
        assert getattr(plant, name) == pytest.approx(getattr(want, name), rel=1e-6), name
    assert (plant.k1, plant.k2, plant.gamma1, plant.gamma2, plant.kc, plant.hmax) == (3.33, 3.35, 0.7, 0.6, 0.5, 20.0)
    assert PRESET.operating_levels() == pytest.approx((12.4, 12.7, 1.8, 1.4), abs=1e-12)


def test_nonminphase_setting() -> None:
    p = NAMED_SETTINGS["nonminphase"]
    plant = p.quadtank_constants()
    assert (plant.k1, plant.k2, plant.gamma1, plant.gamma2) == (3.14, 3.29, 0.43, 0.34)
    assert p.operating_levels() == pytest.approx(P_PLUS.op.x, abs=1e-12)
    assert (p.controllers[0].pid.K, p.controllers[0].pid.Ti) == (1.5, 110.0)
    assert (p.controllers[3].pid.K, p.controllers[3].pid.Ti) == (-0.12, 220.0)
    assert [r.mean for r in p.references] == [0.315, 0.315]


def test_general_defaults_are_the_same_pi() -> None:
    g = PRESET.controllers[0].general
    assert g.numerator == (3.0, 0.1) and g.denominator == (1.0, 0.0)


def test_every_key_is_readable_and_named_as_in_the_file() -> None:
    names = list(iter_keys())
    assert len(names) == len(set(names)) == 133  # 114 of the original + 7 STATE FEEDBACK + 12 MPC
    assert names[0] == "SAMPLING TIME.TSamp"
    for name in ("REFERENCE ONE.Mean", "CONTROLLER ONE.K", "SIMULATION.Valve1", "CONTROLLER FOUR.r4",
                 "SIMULATION.TimeConst3", "LOGGING.Variables", "PLOTS.Lower", "REFERENCE TWO.Seed"):
        assert name in names
    values = PRESET.values()
    assert values["CONTROLLER ONE.K"] == 3.0
    assert values["SIMULATION.Valve1"] == 0.7
    assert values["REFERENCE ONE.Wave"] is Wave.SQUARE
    assert values["CONTROLLER ONE.I"] is True
    assert values["CONTROLLER ONE.Degree"] == 1


def test_with_value_returns_a_new_model_and_keeps_the_old() -> None:
    p = PRESET.with_value("REFERENCE ONE.Mean", 0.4)
    assert p.get("REFERENCE ONE.Mean") == 0.4
    assert PRESET.get("REFERENCE ONE.Mean") == 0.3
    assert p.modified_keys(PRESET) == {"REFERENCE ONE.Mean"}
    assert p.is_modified("REFERENCE ONE.Mean", PRESET) and not p.is_modified("REFERENCE TWO.Mean", PRESET)
    assert PRESET.modified_keys(PRESET) == frozenset()


def test_with_defaults_resets_a_window() -> None:
    p = PRESET.with_values({"CONTROLLER ONE.K": 1.0, "CONTROLLER ONE.Ti": 10, "CONTROLLER FOUR.K": 2.0})
    back = p.with_defaults((k.name for k in keys_of("CONTROLLER ONE")), PRESET)
    assert back.modified_keys(PRESET) == {"CONTROLLER FOUR.K"}
    other = NAMED_SETTINGS["nonminphase"]
    assert PRESET.with_defaults(["SIMULATION.Valve1"], other).get("SIMULATION.Valve1") == 0.43


def test_modified_against_another_default() -> None:
    p = NAMED_SETTINGS["nonminphase"]
    changed = p.modified_keys(PRESET)
    assert "SIMULATION.Valve1" in changed and "CONTROLLER ONE.K" in changed
    assert "SAMPLING TIME.TSamp" not in changed
    assert p.modified_keys(p) == frozenset()


def test_coercion_from_typed_and_loose_values() -> None:
    p = PRESET.with_values({
        "CONTROLLER ONE.I": 0, "CONTROLLER ONE.Degree": 2.0, "CONTROL.Mode": "automatic",
        "REFERENCE ONE.Wave": "prbs", "REFERENCE ONE.Period": 10, "PLOTS.Upper": "y1   y2  y3 y4",
        "LOGGING.Variables": "t y1 r1", "CONTROL.Structure": "FullMatrix",
    })
    assert p.get("CONTROLLER ONE.I") is False
    assert p.get("CONTROLLER ONE.Degree") == 2 and isinstance(p.get("CONTROLLER ONE.Degree"), int)
    assert p.control.mode is ControlMode.AUTOMATIC
    assert p.references[0].wave is Wave.PRBS
    assert p.plots.upper == "y1 y2 y3 y4"
    assert p.logging.variables == ("t", "y1", "r1")
    assert p.control.structure is Structure.FULL_MATRIX


@pytest.mark.parametrize(
    "key, value, reason",
    [
        ("SIMULATION.Valve1", 1.5, "must be <= 1, got 1.5"),
        ("SAMPLING TIME.TSamp", 10, "must be >= 50, got 10"),
        ("SAMPLING TIME.TSamp", 20_000, "must be <= 10000, got 20000"),
        ("REFERENCE ONE.Mean", "x", "must be a number, got 'x'"),
        ("REFERENCE TWO.Amplitude", -0.1, "must be >= 0, got -0.1"),
        ("CONTROLLER TWO.a", 2, "must be <= 1, got 2"),
        ("CONTROLLER THREE.Ti", 0, "must be > 0, got 0"),
        ("CONTROLLER ONE.Degree", 5, "must be an integer 0..4, got 5"),
        ("CONTROLLER ONE.Degree", 1.5, "must be a whole number, got 1.5"),
        ("CONTROLLER ONE.s2", math.nan, "must be a finite number, got nan"),
        ("CONTROLLER ONE.s2", 1e300, "must be within +-1e+09, got 1e+300"),
        ("CONTROLLER ONE.I", 2, "must be 0 or 1, got 2"),
        ("CONTROL.Mode", "auto", "must be one of Manual, Automatic; got 'auto'"),
        ("SIMULATION.Diameter4", 0.1, "must be >= 0.5, got 0.1"),
        ("SIMULATION.OpPoint2", 0, "must be >= 0.001, got 0"),
        ("SIMULATION.OpPoint3", 4.9e-324, "must be >= 0.001, got 4.94066e-324"),  # plant() failed on it
        ("SIMULATION.TimeConst1", 0.5, "must be >= 1, got 0.5"),
        ("SIMULATION.Sensor", 0, "must be >= 0.05, got 0"),
        ("SIMULATION.Pump2", 0, "must be > 0, got 0"),
        ("LOGGING.Points", 0, "must be >= 1, got 0"),
        ("LOGGING.Points", 100_001, "must be <= 100000, got 100001"),
        ("LOGGING.Points", 1e20, "must be <= 100000, got 1e+20"),
        # which names a log, its columns and the plots may have: tests/files/test_names.py
        ("LOGGING.Variables", "", "must be one or more names, got ()"),
        ("LOGGING.LogFile", "", "must be a file name, got ''"),
        ("PLOTS.Lower", "  ", "must be a plot type, got '  '"),
        ("REFERENCE ONE.Period", 0.1, "0.1 s is shorter than twice the sampling time (0.1 s): the shortest allowed is 0.2 s"),
    ],
)
def test_refused_values_name_the_key(key: str, value: object, reason: str) -> None:
    with pytest.raises(ParameterError) as info:
        PRESET.with_value(key, value)
    assert info.value.field == key
    assert info.value.reason == reason
    assert str(info.value) == f"{key}: {reason}"


def test_prbs_period_is_whole_samples() -> None:
    with pytest.raises(ParameterError) as info:
        PRESET.with_values({"REFERENCE TWO.Wave": "PRBS", "REFERENCE TWO.Period": 2.5})
    assert info.value.field == "REFERENCE TWO.Period"
    assert PRESET.with_values({"REFERENCE TWO.Wave": "PRBS", "REFERENCE TWO.Period": 1}).references[1].period == 1.0


def test_joint_changes_are_validated_together() -> None:
    """A 5 s sampling time with a 6 s period is refused alone but fine with a
    longer period set in the same call."""
    with pytest.raises(ParameterError):
        PRESET.with_values({"REFERENCE ONE.Period": 6.0, "SAMPLING TIME.TSamp": 5000})
    p = PRESET.with_values({"REFERENCE ONE.Period": 12.0, "SAMPLING TIME.TSamp": 5000})
    assert p.tsamp == 5.0


def test_unknown_key() -> None:
    with pytest.raises(KeyError, match="unknown parameter 'CONTROLLER FIVE.K'"):
        PRESET.get("CONTROLLER FIVE.K")
    with pytest.raises(KeyError):
        PRESET.with_value("SIMULATION.Valve3", 0.5)


def test_the_model_is_frozen() -> None:
    with pytest.raises(AttributeError):
        PRESET.tsamp_ms = 200.0  # type: ignore[misc]
    assert isinstance(PRESET, Parameters)
    assert spec("CONTROLLER ONE.K").path == ("controllers", 0, "pid", "K")
    assert all(k.name == f"{k.section}.{k.key}" for k in KEYS)


def test_thesis_tank_window_values_and_the_setup_relations() -> None:
    """Figures 33 and 39 show tank 1 at Op. Point 0.62, Diameter 5.93, Time Const.
    62.16: through A = pi d^2/4 and a = A sqrt(2 h0/g)/T that is an outlet of
    0.0706 cm^2 (the paper's table says 0.071, which would give T = 61.8 s)."""
    p = PRESET.with_values({"SIMULATION.Diameter1": 5.93, "SIMULATION.OpPoint1": 0.62, "SIMULATION.TimeConst1": 62.16})
    plant = p.quadtank_constants()
    assert plant.A1 == pytest.approx(27.6184, abs=1e-4)
    assert plant.a1 == pytest.approx(0.070645, abs=1e-6)
    assert p.operating_levels()[0] == pytest.approx(12.4)


def test_log_variables_can_grow_and_shrink_through_with_values() -> None:
    # Regression: the tuple was rebuilt element-wise against the old one and cut to
    # its length (four names), so "t y1 y2 u1 u2 r1 r2" became "t y1 y2 u1".
    p = PRESET.with_values({"LOGGING.Variables": "t y1 y2 u1 u2 r1 r2"})
    assert p.logging.variables == ("t", "y1", "y2", "u1", "u2", "r1", "r2")
    assert p.with_value("LOGGING.Variables", "y1").logging.variables == ("y1",)


def test_a_change_rebuilds_only_the_objects_on_its_path() -> None:
    """with_values rebuilds (and validates) the objects holding a changed value and
    shares the rest: a controller's gain leaves the references and the simulation
    the very objects they were, and the other controllers too."""
    p = PRESET.with_values({"CONTROLLER TWO.K": 1.5, "REFERENCE ONE.Mean": 0.4})
    assert p.controllers[1].pid.K == 1.5 and p.references[0].mean == 0.4
    assert p.controllers[1] is not PRESET.controllers[1] and p.references[0] is not PRESET.references[0]
    assert p.simulation is PRESET.simulation and p.logging is PRESET.logging
    assert all(p.controllers[i] is PRESET.controllers[i] for i in (0, 2, 3))
    assert p.references[1] is PRESET.references[1]
    # Every other value as it was, key by key.
    changed = {"CONTROLLER TWO.K", "REFERENCE ONE.Mean"}
    assert {k: v for k, v in p.values().items() if k not in changed} == {
        k: v for k, v in PRESET.values().items() if k not in changed}


def test_every_key_set_to_its_own_value_gives_an_equal_model() -> None:
    """Each key through with_value, its value unchanged: the same model (the path
    copy puts a value back where it came from, for every kind of path)."""
    for k in KEYS:
        assert PRESET.with_value(k.name, PRESET.get(k.name)) == PRESET, k.name


def test_of_several_bad_values_the_first_in_the_model_is_refused() -> None:
    """Whatever order the caller gives them in (a .par's lines, a window's fields),
    as when the whole model was rebuilt: REFERENCE ONE comes before CONTROLLER ONE."""
    for changes in ({"CONTROLLER ONE.K": 5000, "REFERENCE ONE.Mean": 9},
                    {"REFERENCE ONE.Mean": 9, "CONTROLLER ONE.K": 5000}):
        with pytest.raises(ParameterError) as info:
            PRESET.with_values(changes)
        assert info.value.field == "REFERENCE ONE.Mean"
