"""The number checks of every validated setting (plumbing: imports nothing of the package but
:mod:`math` and :mod:`numbers`, so the settings, the maps, the data layers and the study tables
share them).

NumPy scalars: ``np.float64`` is a subclass of float and passes :func:`is_number` as one;
``np.float32``, ``np.int64`` and the other NumPy scalars are neither int nor float and are
refused (the settings convert them first: :class:`spcopyro.config.SpCoConfig`). Two integer
checks, for two kinds of argument: :func:`is_int` takes a Python int only (``np.int64`` refused,
as ``isinstance(v, int)`` refused it), :func:`is_integer` any integral number (``np.int64``,
``np.uint8`` too). Every check here refuses a bool."""

from __future__ import annotations

import math
import numbers


def is_number(value: object) -> bool:
    """Whether ``value`` is an int or a float, not a bool (True is an int): the number check
    of every validated field of the settings (:mod:`spcopyro.config`), of the footprint's own
    arguments, of a feature scaling, of a map's yaml, of spcoa's pair distance and of the SVI
    options (:class:`spcopyro.guides.svi_method.SVIOptions`)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def is_finite_number(value: object) -> bool:
    """Whether ``value`` is a finite number: :func:`is_number` and neither nan nor +-inf
    (:math:`|x| < \\infty`). -0.0 and 0 pass. An int too large for a float raises
    OverflowError (from :func:`math.isfinite`), as the checks written out did."""
    return is_number(value) and math.isfinite(value)  # type: ignore[arg-type]


def is_positive_number(value: object) -> bool:
    """Whether ``value`` is a finite number > 0 (:math:`0 < x < \\infty`): a scale, a rate or
    a concentration. 0 and -0.0 fail. A bool always (``bool(value > 0)``: an np.float64's
    comparison gives np.bool_)."""
    return is_finite_number(value) and bool(value > 0)  # type: ignore[operator]


def is_int(value: object) -> bool:
    """Whether ``value`` is a Python int, not a bool (True is an int, and was taken as 1): the
    type check of a count (iterations, passes, particles, sweeps) in the methods' options; the
    caller checks the bound. Python ints only: ``np.int64`` is no int and is refused, as
    ``isinstance(value, int)`` refused it (for any integral type, :func:`is_integer`)."""
    return isinstance(value, int) and not isinstance(value, bool)


def is_integer(value: object) -> bool:
    """Whether ``value`` is any integral number, not a bool: a Python int or a NumPy integer
    (``np.int64``, ``np.int32``, ``np.uint8``: NumPy registers ``np.integer`` as
    :class:`numbers.Integral`), for the arguments a caller may take out of an array (a seed, a
    concept index, a sweep count, an image side); the caller checks the bound. True and
    ``np.bool_`` are refused (``np.bool_`` is no Integral; True is an int, taken as 1), and so is
    a float with an integral value (3.0). For a Python int only, :func:`is_int`."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)
