"""spcopyro._util.number_checks: the number checks the settings, the maps, the data layers and
the study tables share (is_number, is_finite_number, is_positive_number)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spcopyro._util.number_checks import is_finite_number, is_number, is_positive_number

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
