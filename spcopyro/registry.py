"""The inference methods of spcopyro, by name: ``spcopyro fit --method NAME``,
:func:`spcopyro.fit.fit_house(method=NAME) <spcopyro.fit.fit_house>` and the experiments read
this table. A new method is one module implementing :class:`~spcopyro.inference.InferenceMethod`
and one entry here.
"""

from __future__ import annotations

from spcopyro.gibbs.method import GibbsInference
from spcopyro.guides.method import SVIInference
from spcopyro.inference import InferenceMethod
from spcopyro.variational.lbp_method import LBPInference
from spcopyro.variational.method import CAVIInference
from spcopyro.variational.stochastic import StochasticVIInference
from spcopyro.variational.vi_gibbs import VIGibbsInference

INFERENCE_METHODS: dict[str, InferenceMethod] = {
    "gibbs": GibbsInference(),
    "cavi": CAVIInference(),
    "lbp": LBPInference(),
    "svi": SVIInference(),
    "stochastic-vi": StochasticVIInference(),
    "vi-gibbs": VIGibbsInference(),
}
DEFAULT_METHOD = "gibbs"


def get_method(name: str) -> InferenceMethod:
    """The inference method called ``name`` (ValueError listing the known ones)."""
    try:
        return INFERENCE_METHODS[name]
    except KeyError:
        raise ValueError(
            f"unknown inference method {name!r}; choose one of {sorted(INFERENCE_METHODS)}"
        ) from None
