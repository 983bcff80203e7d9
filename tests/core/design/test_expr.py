"""The model-expression parser: what it reads, and where it says a bad one is wrong."""

from __future__ import annotations

import numpy as np
import pytest

from quadtank_tui.core.design.expr import ExprError, parse_model


def test_andersson_process_1() -> None:
    g = parse_model("1.6592*exp(-2.4*s)/(1.07*s+1)^3")
    assert g.num == (1.6592,)
    np.testing.assert_allclose(g.den, [1.07**3, 3 * 1.07**2, 3 * 1.07, 1.0])
    assert g.delay == 2.4 and g.integrators == 0


def test_integrating_negative_gain() -> None:
    g = parse_model("-0.00652*exp(-2*s)/(s*(49.33*s+1))")
    assert g.num == (-0.00652,) and g.den == (49.33, 1.0, 0.0)
    assert g.integrators == 1 and g.static_gain == pytest.approx(-0.00652)


@pytest.mark.parametrize("text", [
    "0.3292(28.978s+1)/(8.58s+1)^3*exp(-2.02s)",  # implicit products
    "0.3292*(28.978*s+1)*(8.58*s+1)^-3*exp(-2.02*s)",  # negative power
    "exp(-1.01*s)*0.3292*(28.978*s+1)/((8.58*s+1)**3)*exp(-1.01*s)",  # two delay factors
])
def test_equivalent_spellings(text: str) -> None:
    g = parse_model(text)
    ref = parse_model("0.3292*(28.978*s+1)/(8.58*s+1)^3*exp(-2.02*s)")
    w = np.logspace(-3, 1, 50)
    np.testing.assert_allclose(g.freqresp(w), ref.freqresp(w), rtol=1e-12)


def test_sums_and_no_delay() -> None:
    g = parse_model("(2*s + 1)/(s^2 + 3*s + 2) - 1/(s+2)")
    np.testing.assert_allclose(g.freqresp(np.array([0.0])), [0.5 - 0.5])
    assert parse_model("1/(s+1)").delay == 0.0


@pytest.mark.parametrize("text, column, words", [
    ("1/(s+1", 7, "expected ')' to close the '(' at column 3"),
    ("2*exp(-s)+1", 10, "only multiply the whole model"),
    ("1/(s+1)^2.5", 9, "integer"),
    ("k/(s+1)", 1, "unknown name 'k'"),
    ("1/(s+1) $", 9, "unexpected character '$'"),
    ("exp(-s^2)/(s+1)", 4, "argument of exp"),
    ("1/0", 2, "division by zero"),
    ("", 1, "empty"),
    ("1/(s+1)*", 9, "expected a number"),
    ("s^2/(s+1)", 1, "improper"),
    ("exp(2*s)/(s+1)", 1, "dead time must be >= 0"),
])
def test_errors_point_at_the_character(text: str, column: int, words: str) -> None:
    with pytest.raises(ExprError) as info:
        parse_model(text)
    err = info.value
    assert err.column == column
    assert words in str(err)
    lines = str(err).splitlines()
    assert lines[1] == "  " + text and lines[2] == "  " + " " * (column - 1) + "^"


def test_never_evaluates_python() -> None:
    with pytest.raises(ExprError, match="column 12: unexpected character"):
        parse_model("__import__('os').system('true')")
    with pytest.raises(ExprError, match="unknown name '__import__'"):
        parse_model("__import__(s)")


# --- bounded work on hostile input (issue 24: a 130 KB expression took 15.8 s) ---------

def test_an_expression_longer_than_the_cap_is_refused_with_its_length() -> None:
    text = "1/(s+1)" + "+0" * 600
    with pytest.raises(ExprError, match=f"the expression has {len(text)} characters; a model has at most 1000"):
        parse_model(text)


def test_parentheses_nested_too_deep_are_refused_at_the_parenthesis() -> None:
    with pytest.raises(ExprError, match="parentheses nested more than 50 deep") as err:
        parse_model("(" * 60 + "s+1" + ")" * 60)
    assert err.value.column == 51


def test_a_long_run_of_signs_does_not_recurse() -> None:
    g = parse_model("-" * 993 + "1/(s+1)")  # an odd number of minus signs: -1/(s+1)
    assert g.num == (-1.0,) and g.den == (1.0, 1.0)


@pytest.mark.parametrize("text", [
    "(s+1)" * 100,               # a product of a hundred factors
    "1/((s+1)^20)^20",           # powers of powers
    "(2s+1)^20*(3s+1)^20*(s+1)^20*(4s+1)",
])
def test_a_model_whose_order_explodes_is_refused(text: str) -> None:
    with pytest.raises(ExprError, match="order grows above 60"):
        parse_model(text)
