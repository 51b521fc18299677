"""The number check of every validated setting (plumbing: imports nothing of the package, so
the settings, the maps and the data layers share it)."""

from __future__ import annotations


def is_number(value: object) -> bool:
    """Whether ``value`` is an int or a float, not a bool (True is an int): the number check
    of every validated field of the settings (:mod:`spcopyro.config`), of the footprint's own
    arguments, of a feature scaling, of a map's yaml, of spcoa's pair distance and of the SVI
    options (:class:`spcopyro.guides.svi_method.SVIOptions`)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)
