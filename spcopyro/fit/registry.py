"""The inference methods of spcopyro, by name: ``spcopyro fit --method NAME``,
:func:`spcopyro.fit.house.fit_house(method=NAME) <spcopyro.fit.house.fit_house>` and the
experiments read this table. A new method is one module implementing
:class:`~spcopyro.inference.protocol.InferenceMethod` and one entry here, its name also in
:data:`spcopyro.inference.names.INFERENCE_METHOD_NAMES` (checked on import).
"""

from __future__ import annotations

from spcopyro.gibbs.method import GibbsInference
from spcopyro.guides.cavi_method import CAVIInference
from spcopyro.guides.lbp_method import LBPInference
from spcopyro.guides.memoized import StochasticVIInference
from spcopyro.guides.svi_method import SVIInference
from spcopyro.guides.vi_gibbs import VIGibbsInference
from spcopyro.inference.names import DEFAULT_METHOD, INFERENCE_METHOD_NAMES
from spcopyro.inference.protocol import InferenceMethod

INFERENCE_METHODS: dict[str, InferenceMethod] = {
    "gibbs": GibbsInference(),
    "cavi": CAVIInference(),
    "lbp": LBPInference(),
    "svi": SVIInference(),
    "stochastic-vi": StochasticVIInference(),
    "vi-gibbs": VIGibbsInference(),
}


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
