"""spcopyro._util.number_checks: the number checks the settings, the maps, the data layers and
the study tables share (is_number, is_finite_number, is_positive_number), the count check of
the methods' options (is_int: a Python int) and of arguments that may come out of an array
(is_integer: any integral number)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spcopyro._util.number_checks import (
    is_finite_number,
    is_int,
    is_integer,
    is_number,
    is_positive_number,
)

CASES = [  # value, is_number, is_finite_number, is_positive_number
    (True, False, False, False),  # True is an int, no number
    (False, False, False, False),
    (0, True, True, False),
    (-0.0, True, True, False),
    (0.0, True, True, False),
    (3, True, True, True),
    (2.5, True, True, True),
    (-1.5, True, True, False),
    (5e-324, True, True, True),  # the smallest subnormal is > 0
    (math.nan, True, False, False),
    (math.inf, True, False, False),
    (-math.inf, True, False, False),
    (np.float64(0.5), True, True, True),  # a float subclass: passes as a float
    (np.float64(math.nan), True, False, False),
    (np.float64(-0.0), True, True, False),
    (np.float32(0.5), False, False, False),  # neither int nor float: refused
    (np.int64(5), False, False, False),
    (np.bool_(True), False, False, False),
    (None, False, False, False),
    ("1.0", False, False, False),
    ([1.0], False, False, False),
]


@pytest.mark.parametrize(("value", "number", "finite", "positive"), CASES, ids=repr)
def test_number_checks(value: object, number: bool, finite: bool, positive: bool) -> None:
    """Each returns a bool, True or False itself (``is``): not np.True_ from a comparison of an
    np.float64, which the declared ``-> bool`` promises not to return."""
    assert is_number(value) is number
    assert is_finite_number(value) is finite
    assert is_positive_number(value) is positive


def test_huge_int_raises_as_math_isfinite_does() -> None:
    """An int too large for a float: math.isfinite's OverflowError, as the checks written out
    before these helpers raised it."""
    with pytest.raises(OverflowError):
        is_finite_number(10**400)
    with pytest.raises(OverflowError):
        is_positive_number(10**400)


@pytest.mark.parametrize(
    ("value", "integer"),
    [
        (0, True),
        (3, True),
        (-2, True),
        (10**400, True),
        (True, False),
        (False, False),
        (np.int64(5), False),
        (np.bool_(True), False),
        (3.0, False),
        (np.float64(3.0), False),
        (None, False),
        ("3", False),
    ],
    ids=repr,
)
def test_is_int_is_an_int_and_no_bool(value: object, integer: bool) -> None:
    """True is an int, and a count given True was taken as 1; NumPy integers are no int."""
    assert is_int(value) is integer


@pytest.mark.parametrize(
    ("value", "integer"),
    [
        (0, True),
        (-2, True),
        (10**400, True),
        (np.int64(5), True),  # numpy registers np.integer as numbers.Integral
        (np.int32(-5), True),
        (np.uint8(255), True),
        (True, False),
        (False, False),
        (np.bool_(True), False),  # np.bool_ is no Integral
        (np.bool_(False), False),
        (3.0, False),
        (np.float64(3.0), False),
        (np.float32(3.0), False),
        (None, False),
        ("3", False),
        (np.array(3), False),  # a 0-d array is no scalar
    ],
    ids=repr,
)
def test_is_integer_is_any_integral_number_and_no_bool(value: object, integer: bool) -> None:
    """is_integer takes what ``isinstance(v, int | np.integer) and not isinstance(v, bool)``
    took, the check it replaced (a seed, a concept index, a sweep count, an image side): NumPy
    integers too, where is_int refuses them; a bool of either kind never."""
    assert is_integer(value) is integer
    replaced = isinstance(value, int | np.integer) and not isinstance(value, bool)
    assert replaced is integer
    assert is_int(value) is (integer and isinstance(value, int))
