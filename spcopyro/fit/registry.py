"""The inference methods of spcopyro, by name: ``spcopyro fit --method NAME``,
:func:`spcopyro.fit.house.fit_house(method=NAME) <spcopyro.fit.house.fit_house>` and the
experiments read this table. A new method is one module implementing
:class:`~spcopyro.inference.protocol.InferenceMethod` and one entry here, its name also in
:data:`spcopyro.inference.names.INFERENCE_METHOD_NAMES` (checked on import).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, MutableMapping

from spcopyro.inference.names import DEFAULT_METHOD, INFERENCE_METHOD_NAMES
from spcopyro.inference.protocol import InferenceMethod

# Each method's module is imported when the method is first looked up: the variational methods
# import what a Gibbs fit never runs (svi: Pyro, about 200 modules, 0.05-0.1 s of its start-up).


def _gibbs() -> InferenceMethod:
    from spcopyro.gibbs.method import GibbsInference

    return GibbsInference()


def _cavi() -> InferenceMethod:
    from spcopyro.guides.cavi_method import CAVIInference

    return CAVIInference()


def _lbp() -> InferenceMethod:
    from spcopyro.guides.lbp_method import LBPInference

    return LBPInference()


def _svi() -> InferenceMethod:
    from spcopyro.guides.svi_method import SVIInference

    return SVIInference()


def _stochastic_vi() -> InferenceMethod:
    from spcopyro.guides.memoized import StochasticVIInference

    return StochasticVIInference()


def _vi_gibbs() -> InferenceMethod:
    from spcopyro.guides.vi_gibbs import VIGibbsInference

    return VIGibbsInference()


class _Methods(MutableMapping[str, InferenceMethod]):
    """A dict of the methods by name whose values are made (their modules imported) when first
    read; names, order, ``in`` and ``len`` need no import."""

    def __init__(self, loaders: dict[str, Callable[[], InferenceMethod]]) -> None:
        self._loaders: dict[str, Callable[[], InferenceMethod] | None] = dict(loaders)
        self._methods: dict[str, InferenceMethod] = {}

    def __getitem__(self, name: str) -> InferenceMethod:
        if name not in self._methods:
            loader = self._loaders[name]  # KeyError for an unknown name, as a dict's
            assert loader is not None  # a name set by hand is in _methods
            self._methods[name] = loader()
        return self._methods[name]

    def __setitem__(self, name: str, method: InferenceMethod) -> None:
        self._loaders.setdefault(name, None)  # a new name goes last, as in a dict
        self._methods[name] = method

    def __delitem__(self, name: str) -> None:
        del self._loaders[name]
        self._methods.pop(name, None)

    def __contains__(self, name: object) -> bool:
        return name in self._loaders

    def __iter__(self) -> Iterator[str]:
        return iter(self._loaders)

    def __len__(self) -> int:
        return len(self._loaders)

    def __repr__(self) -> str:
        return f"INFERENCE_METHODS{tuple(self._loaders)}"


INFERENCE_METHODS: MutableMapping[str, InferenceMethod] = _Methods(
    {
        "gibbs": _gibbs,
        "cavi": _cavi,
        "lbp": _lbp,
        "svi": _svi,
        "stochastic-vi": _stochastic_vi,
        "vi-gibbs": _vi_gibbs,
    }
)
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
