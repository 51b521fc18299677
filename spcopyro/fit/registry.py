"""The inference methods of spcopyro, by name: ``spcopyro fit --method NAME``,
:func:`spcopyro.fit.house.fit_house(method=NAME) <spcopyro.fit.house.fit_house>` and the
experiments read this table. A new method is one module implementing
:class:`~spcopyro.inference.protocol.InferenceMethod` and one entry here, its name also in
:data:`spcopyro.inference.names.INFERENCE_METHOD_NAMES` (checked on import).
"""

from __future__ import annotations

from collections.abc import Iterator, MutableMapping
from typing import TYPE_CHECKING

from spcopyro._util.lazy import load
from spcopyro.inference.names import DEFAULT_METHOD, INFERENCE_METHOD_NAMES
from spcopyro.inference.protocol import InferenceMethod

if TYPE_CHECKING:  # pragma: no cover (the import graph's edges, tests/test_architecture.py)
    from spcopyro.gibbs.method import GibbsInference
    from spcopyro.guides.cavi_method import CAVIInference
    from spcopyro.guides.lbp_method import LBPInference
    from spcopyro.guides.memoized import StochasticVIInference
    from spcopyro.guides.svi_method import SVIInference
    from spcopyro.guides.vi_gibbs import VIGibbsInference

    _Made = (
        GibbsInference
        | CAVIInference
        | LBPInference
        | SVIInference
        | StochasticVIInference
        | VIGibbsInference
    )

_CLASSES: dict[str, tuple[str, str]] = {
    "gibbs": ("spcopyro.gibbs.method", "GibbsInference"),
    "cavi": ("spcopyro.guides.cavi_method", "CAVIInference"),
    "lbp": ("spcopyro.guides.lbp_method", "LBPInference"),
    "svi": ("spcopyro.guides.svi_method", "SVIInference"),
    "stochastic-vi": ("spcopyro.guides.memoized", "StochasticVIInference"),
    "vi-gibbs": ("spcopyro.guides.vi_gibbs", "VIGibbsInference"),
}
"""Each method's name and its class (module, class name), made when the method is first looked
up: the variational methods import what a Gibbs fit never runs (svi: Pyro, about 200 modules,
0.05-0.1 s of its start-up)."""


def _make(module: str, cls: str) -> _Made:
    """The method of class ``cls`` of ``module``, its module imported first."""
    return load(module, cls)()


class _Methods(MutableMapping[str, InferenceMethod]):
    """A dict of the methods by name whose values are made (their modules imported) when first
    read; names, order, ``in`` and ``len`` need no import."""

    def __init__(self, classes: dict[str, tuple[str, str]]) -> None:
        self._classes: dict[str, tuple[str, str] | None] = dict(classes)
        self._methods: dict[str, InferenceMethod] = {}

    def __getitem__(self, name: str) -> InferenceMethod:
        if name not in self._methods:
            home = self._classes[name]  # KeyError for an unknown name, as a dict's
            assert home is not None  # a name set by hand is in _methods
            self._methods[name] = _make(*home)
        return self._methods[name]

    def __setitem__(self, name: str, method: InferenceMethod) -> None:
        self._classes.setdefault(name, None)  # a new name goes last, as in a dict
        self._methods[name] = method

    def __delitem__(self, name: str) -> None:
        del self._classes[name]
        self._methods.pop(name, None)

    def __contains__(self, name: object) -> bool:
        return name in self._classes

    def __iter__(self) -> Iterator[str]:
        return iter(self._classes)

    def __len__(self) -> int:
        return len(self._classes)

    def __repr__(self) -> str:
        return f"INFERENCE_METHODS{tuple(self._classes)}"


INFERENCE_METHODS: MutableMapping[str, InferenceMethod] = _Methods(_CLASSES)
"""Every method by name, in :data:`~spcopyro.inference.names.INFERENCE_METHOD_NAMES`' order;
a method's module is imported when it is first looked up."""


__all__ = ["DEFAULT_METHOD", "INFERENCE_METHODS", "get_method"]

if tuple(INFERENCE_METHODS) != INFERENCE_METHOD_NAMES:  # the command line lists the names
    raise ImportError(
        f"spcopyro.inference.names.INFERENCE_METHOD_NAMES {INFERENCE_METHOD_NAMES} must list "
        f"the registry's methods {tuple(INFERENCE_METHODS)}, in order"
    )


def get_method(name: str) -> InferenceMethod:
    """The inference method called ``name`` (ValueError listing the known ones)."""
    try:
        return INFERENCE_METHODS[name]
    except KeyError:
        raise ValueError(
            f"unknown inference method {name!r}; choose one of {sorted(INFERENCE_METHODS)}"
        ) from None
