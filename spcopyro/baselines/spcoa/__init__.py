r"""Baseline (C): spatial concept formation with words and images (SpCoA style).

The comparison method (C) of SpCoMapping (Katsumata et al., 2019, Table 4): a mixture over
*observations*, not map cells, as in

* Ishibushi, Taniguchi, Takano, Hagiwara and Inamura (2015), "Statistical localization exploiting
  convolutional neural network for an autonomous vehicle", IECON 2015 (spatial concepts with CNN
  place-class features), and
* Taniguchi, Hagiwara, Taniguchi and Inamura (2016), "Online spatial concept and lexical
  acquisition with simultaneous localization and mapping" / SpCoA (Nonparametric Bayesian spatial
  concept acquisition, IROS 2016): concepts with a Gaussian position distribution and
  multinomial word emissions.

The package, one module per responsibility:

* :mod:`~spcopyro.baselines.spcoa.events`: the observation events the mixture clusters (images,
  with the utterances paired to them) -- :class:`SpCoAData`, :func:`spcoa_data`.
* :mod:`~spcopyro.baselines.spcoa.niw`: the normal-inverse-Wishart conjugate pieces of the
  position Gaussians -- :func:`niw_posterior`, :func:`niw_log_marginal`, :func:`sample_niw`.
* :mod:`~spcopyro.baselines.spcoa.sampler`: the generative model and its blocked Gibbs sampler
  -- :class:`SpCoAHyperparameters`, :class:`EventTensors`, :class:`SpCoAParameters`,
  :func:`assignment_logits`, :func:`sample_globals`, :func:`collapsed_log_joint`,
  :func:`fit_spcoa`, and :func:`spcoa_gaussians` (SpCoMapping's pre-learning initialisation).
* :mod:`~spcopyro.baselines.spcoa.result`: the fitted model and the semantic map it makes
  (paper eqs. 21-22) -- :class:`SpCoAResult`.

Nothing here imports SpCoMapping's sampler: the random draws come from
:mod:`spcopyro._util.random_draws`, the cell labelling from
:mod:`spcopyro.inference.initialisation`.
"""

from spcopyro.baselines.spcoa.events import DEFAULT_PAIR_DISTANCE, SpCoAData, spcoa_data
from spcopyro.baselines.spcoa.niw import DIM, niw_log_marginal, niw_posterior, sample_niw
from spcopyro.baselines.spcoa.result import SpCoAResult
from spcopyro.baselines.spcoa.sampler import (
    EventTensors,
    SpCoAHyperparameters,
    SpCoAParameters,
    assignment_logits,
    collapsed_log_joint,
    fit_spcoa,
    sample_globals,
    spcoa_gaussians,
)

__all__ = [
    "DEFAULT_PAIR_DISTANCE",
    "DIM",
    "EventTensors",
    "SpCoAData",
    "SpCoAHyperparameters",
    "SpCoAParameters",
    "SpCoAResult",
    "assignment_logits",
    "collapsed_log_joint",
    "fit_spcoa",
    "niw_log_marginal",
    "niw_posterior",
    "sample_globals",
    "sample_niw",
    "spcoa_data",
    "spcoa_gaussians",
]
