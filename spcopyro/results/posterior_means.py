r"""The posterior means of pi and of every modality's distributions given label maps.

A Gibbs state holds one *draw* of pi, theta and w (Algorithm 1, eqs. 14-17). A single draw is a
poor summary for a person: a concept with few observations gets word probabilities that swing
from draw to draw, and a concept with none gets a random draw from its prior, which reads like
a learnt word list ("parlor 0.85"). Given the labels C, every global is conjugate, so its
posterior mean is exact (the Dirichlet updates of eqs. 14-17, in mean):

.. math::

    E[\phi^{(m)}_{lk} \mid C, x] = \frac{a_m + n^{(m)}_{lk}}{K_m a_m + n^{(m)}_l},
    \qquad
    E[\pi_l \mid C] = \frac{c + N_l}{L c + N},

with :math:`n^{(m)}_{lk}` the counts of item k of modality m over the observed cells labelled l,
:math:`n^{(m)}_l = \sum_k n^{(m)}_{lk}`, :math:`a_m` the modality's concentration (beta for
words, chi for images), :math:`N_l` the cells labelled l and c = alpha/L (weak-limit DP, eq. 7)
or alpha (Dirichlet prior). For words this is :math:`(\beta + n_{lv}) / (V\beta + n_l)`. The
paper averages 100 draws of w_l (Section 5: "we sample w_l for 100 times and use the average");
that average is a Monte Carlo estimate of exactly this mean, which is computed here without the
Monte Carlo error. A concept that holds no observation gets its prior mean, the uniform
distribution, not a random draw.

Where a fit kept label maps C^(1..S) (``fit --marginal-samples``), the posterior mean of the
globals given the data is estimated by averaging the means given each map (Rao-Blackwellisation,
:func:`posterior_means` with ``[S, N]`` labels):

.. math::

    E[\phi_l \mid x] \approx \frac{1}{S} \sum_s E[\phi_l \mid C^{(s)}, x].

The concepts are matched across the maps by their ids, as the label frequencies of
:func:`spcopyro.results.uncertainty.label_frequencies` are: a Gibbs chain keeps a region's id while
the
region lives (no relabelling move but the Swendsen-Wang move changes ids of whole regions), and a
concept absent from some maps contributes its prior mean from those maps.

A modality switched off in the config (``use_images`` / ``use_words``,
:meth:`~spcopyro.config.SpCoConfig.uses`) has no counts in the statistics, so its means are its
prior's.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import torch

from spcopyro._util.number_checks import is_positive_number
from spcopyro.config import WORDS, SpCoConfig
from spcopyro.inference.protocol import InferenceOutput
from spcopyro.likelihood import concept_statistics
from spcopyro.model import DTYPE, ModelData

__all__ = [
    "PARAMETERS_DRAWN",
    "PARAMETERS_GIVEN_LABELS",
    "concept_totals",
    "concept_word_counts",
    "posterior_means",
    "with_posterior_means",
    "words_per_cell",
]

PARAMETERS_DRAWN = "one posterior draw (the sampler's state)"
PARAMETERS_GIVEN_LABELS = "posterior mean given the point labels"


def _as_samples(labels: np.ndarray | torch.Tensor) -> torch.Tensor:
    """[S, N] int64 label maps from ``[N]`` or ``[S, N]`` labels."""
    tensor = torch.as_tensor(np.asarray(labels)).to(torch.long)
    if tensor.dim() == 1:
        tensor = tensor.unsqueeze(0)
    if tensor.dim() != 2 or tensor.shape[0] == 0:
        raise ValueError(f"labels must be [N] or [S >= 1, N], got shape {tuple(tensor.shape)}")
    return tensor


def posterior_means(
    labels: np.ndarray | torch.Tensor, data: ModelData, config: SpCoConfig
) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """E[pi | C] ``[L]`` and E[phi_m | C, x] ``[L, K_m]`` per modality (module docstring),
    averaged over the maps when ``labels`` is ``[S, N]``.

    Raises ValueError for labels outside ``[0, L)`` or not one per free cell.
    """
    samples = _as_samples(labels)  # [S, N]
    num_l = config.num_concepts
    if samples.shape[1] != data.num_free:
        raise ValueError(f"labels hold {samples.shape[1]} cells, the data {data.num_free}")
    if samples.min() < 0 or samples.max() >= num_l:
        raise ValueError(
            f"labels must be concepts in 0..{num_l - 1}, got {int(samples.min())}.."
            f"{int(samples.max())}"
        )
    c = config.pi_concentration
    pi = torch.zeros(num_l, dtype=DTYPE)  # [L]
    tables = [torch.zeros(num_l, m.counts.shape[-1], dtype=DTYPE) for m in data.modalities]
    for sample in samples:  # one map at a time: [N]
        statistics = concept_statistics(sample, data, config)
        pi += (c + statistics.cells) / (num_l * c + data.num_free)
        for table, modality, counts in zip(tables, data.modalities, statistics.counts, strict=True):
            a = config.concentration(modality.name)
            k = counts.shape[-1]
            table += (a + counts) / (k * a + counts.sum(-1, keepdim=True))  # [L, K_m]
    S = samples.shape[0]
    return (pi / S).numpy(), tuple((t / S).numpy() for t in tables)


def concept_totals(
    labels: np.ndarray | torch.Tensor, data: ModelData, config: SpCoConfig
) -> np.ndarray:
    """[L, 1 + n_modalities] per concept under the ``[N]`` labels: the observed cells it holds,
    then each modality's total count there (images, words, further ones in ``data``'s order).
    A modality switched off in the config counts its observations all the same: they were made
    there, whether the model reads them or not."""
    tensor = _as_samples(labels)[0]  # [N]
    num_l = config.num_concepts
    observed = tensor[data.obs_cells]  # [M]
    totals = np.zeros((num_l, 1 + len(data.modalities)))
    totals[:, 0] = torch.bincount(observed, minlength=num_l).numpy()
    for j, modality in enumerate(data.modalities):
        per_cell = modality.counts.sum(-1)  # [M]
        totals[:, 1 + j] = torch.zeros(num_l, dtype=DTYPE).index_add_(0, observed, per_cell)
    return totals


def words_per_cell(data: ModelData, word_scaling: float) -> np.ndarray:
    """[N] float64 the words heard at each free cell (0 off the observed cells): the
    model's word counts divided by ``word_scaling`` (the preparation's
    ``DataPreparation.word_scaling``, by which they were multiplied), the units of
    ``result.heard``, which sums the same counts over a concept's cells (:func:`concept_totals`'
    words column, divided by it). A speck's test (:func:`~spcopyro.results.concept_words.is_speck`,
    :mod:`spcopyro.results.speck_join`) reads them: under
    :data:`~spcopyro.results.concept_words.SPECK_WORDS` words heard in a cluster's cells."""
    if not is_positive_number(word_scaling):
        raise ValueError(f"word_scaling must be a positive finite number, got {word_scaling!r}")
    per_cell = data.modality(WORDS).counts.sum(-1).to(DTYPE).numpy()  # [M]
    counts = np.bincount(data.obs_cells.numpy(), weights=per_cell, minlength=data.num_free)  # [N]
    return counts / float(word_scaling)


def concept_word_counts(
    labels: np.ndarray | torch.Tensor, data: ModelData, config: SpCoConfig
) -> np.ndarray:
    """[L, V] each word's count in each concept's region under the ``[N]`` labels (the model's
    counts, n_lv of the module docstring, counted whether or not the config reads words): the
    rows add up to :func:`concept_totals`' words column. A word whose count is 0 was never heard
    in the concept (:func:`~spcopyro.results.concept_words.heard_words`)."""
    tensor = _as_samples(labels)[0]  # [N]
    counts = data.modality(WORDS).counts  # [M, V]
    table = torch.zeros(config.num_concepts, counts.shape[-1], dtype=DTYPE)  # [L, V]
    return table.index_add_(0, tensor[data.obs_cells], counts.to(DTYPE)).numpy()


def with_posterior_means(
    output: InferenceOutput,
    data: ModelData,
    config: SpCoConfig,
    samples: np.ndarray | None = None,
) -> InferenceOutput:
    """``output`` with its pi and emissions replaced by their posterior means given its point
    labels, or averaged over ``samples`` ``[S, N]`` when given (module docstring), and
    ``options["parameters"]`` saying which."""
    labels = output.labels if samples is None or len(samples) == 0 else samples
    pi, emissions = posterior_means(labels, data, config)
    if labels is output.labels:
        how = PARAMETERS_GIVEN_LABELS
    else:
        how = f"posterior mean averaged over {len(samples)} label samples (Rao-Blackwellised)"
    return dataclasses.replace(
        output,
        pi=pi,
        emissions=emissions,
        parameters_drawn=False,
        options={**output.options, "parameters": how},
    )
