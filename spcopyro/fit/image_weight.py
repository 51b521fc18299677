"""An image weight estimated from a first fit's concepts, and the two-stage fit that uses it
(issue 21, an experiment: docs/real_houses.md, "What is still open").

Preset ``coarse`` counts an image histogram as one observation (``feature_scaling =
"probability"``), right for the public houses, whose CNN histograms follow the view rather than
the place, and too weak for the synthetic houses, whose histograms are drawn cleanly per place
(``auto``'s 100 draws an image win there). Whether the images separate places needs the places;
the first fit's concepts stand in for them (never a truth).

**The statistic.** Images ``i = 1..n`` with histograms ``f_i`` (``[K]``, summing to 1) taken in
cells labelled ``c(i)`` by the first fit; ``G`` concepts holding at least one image; ``phi_g``
the mean histogram of concept ``g``'s images and ``phi`` that of all. The share of the images'
variance the concepts explain, adjusted for the number of groups (so that speck concepts holding
one image each explain nothing by construction)::

    SS_within = sum_i ||f_i - phi_c(i)||^2          SS_total = sum_i ||f_i - phi||^2
    explained = 1 - (SS_within / (n - G)) / (SS_total / (n - 1))

For Dirichlet-distributed histograms ``f ~ Dir(kappa phi)`` (the synthetic houses' generator,
and the moment model of the public ones), ``E ||f - phi||^2 = (1 - ||phi||^2) / (kappa + 1)``,
so ``explained`` is about ``1 - (kappa_whole + 1) / (kappa_within + 1)``: 0 when the concepts'
images are as dispersed as the whole house's, near 1 when the concepts hold tight image
clusters. :class:`ImageSeparation` reports both moment estimates of ``kappa`` beside it.

**The rule** (stated before any fit was scored; its thresholds come from the truth regions'
kappa in docs/real_houses.md: public houses ``kappa`` 10-16 within regions against 8-12 for the
whole house, ``explained`` 0.15-0.31; synthetic and simulated houses 30-34 against 6-8,
``explained`` 0.72-0.80)::

    weight = top ** clip((explained - low) / (high - low), 0, 1)     low 0.4, high 0.6, top 100

one observation an image below ``low``, ``top`` draws (``auto``'s ``floor100``) above ``high``,
geometric in between. :func:`fit_two_stage` fits, estimates the weight, and refits with
``feature_scaling = weight`` warm-started from the first fit's labels.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from spcopyro.config import SpCoSettings
from spcopyro.data import House
from spcopyro.data.model_grid import model_house
from spcopyro.fit.house import fit_house
from spcopyro.fit.image_separation import ImageSeparation, image_labels, image_separation
from spcopyro.results.result import SpCoResult

LOW, HIGH, TOP = 0.4, 0.6, 100.0
"""The rule's thresholds on ``explained`` and the largest weight (module docstring)."""

__all__ = [
    "HIGH", "LOW", "TOP", "ImageSeparation", "TwoStageFit", "fit_two_stage", "image_labels",
    "image_separation", "image_weight",
]  # fmt: skip


def image_weight(explained: float, low: float = LOW, high: float = HIGH, top: float = TOP) -> float:
    """The rule of the module docstring: 1 below ``low``, ``top`` above ``high``, geometric
    between."""
    if not low < high:
        raise ValueError(f"low must be below high, got {low}, {high}")
    share = min(max((explained - low) / (high - low), 0.0), 1.0)
    return float(top**share)


@dataclasses.dataclass(frozen=True)
class TwoStageFit:
    """A two-stage fit: the first fit, its images' separation, the weight and the refit."""

    first: SpCoResult
    separation: ImageSeparation
    weight: float
    result: SpCoResult


def fit_two_stage(
    house: House,
    settings: SpCoSettings,
    *,
    first_sweeps: int,
    second_sweeps: int,
    seed: int = 0,
    low: float = LOW,
    high: float = HIGH,
    top: float = TOP,
    **fit_kwargs: Any,
) -> TwoStageFit:
    """Fit ``settings`` (images as they are), estimate the image weight from the fit's
    concepts (:func:`image_separation`, :func:`image_weight`) and refit with
    ``feature_scaling = weight``, the second fit starting from the first's labels.
    ``fit_kwargs`` go to both :func:`~spcopyro.fit.house.fit_house` calls (``init`` to the first
    only)."""
    house = model_house(house, settings.data.cell_size)
    fit_kwargs = {**fit_kwargs, "refine": "never"}  # this experiment's own second stage
    first = fit_house(house, settings, sweeps=first_sweeps, seed=seed, **fit_kwargs)
    separation = image_separation(house.observations.image_features, image_labels(first, house))
    weight = image_weight(separation.explained, low, high, top)
    refit_settings = settings.replace(feature_scaling=weight)
    second_kwargs = {**fit_kwargs, "init": first}
    result = fit_house(house, refit_settings, sweeps=second_sweeps, seed=seed + 1, **second_kwargs)
    return TwoStageFit(first, separation, weight, result)
