"""The refusals the inference tools run on the model they are given (a trace of it, or the
model wrapped): :class:`~spcopyro.gibbs.SpCoGibbs` and
:class:`~spcopyro.guides.loss.MeanFieldELBO` sample or fit
:func:`~spcopyro.model.spcomapping_model`'s own conditionals, so each refuses a model that holds
one of its latent sites fixed (:func:`refuse_observed_latents`), has a site it has not
(:func:`refuse_foreign_sites`), or draws its observations instead of observing them
(:func:`require_observed`). The checks of the model's own inputs (:class:`~spcopyro.model.ModelData`
and :class:`~spcopyro.config.SpCoConfig`, :func:`~spcopyro.model.check_model_data`) run inside the
model and stay in :mod:`spcopyro.model`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import pyro
import torch
from pyro.poutine.messenger import Messenger
from pyro.poutine.util import site_is_subsample

from spcopyro.config import concentration_name
from spcopyro.model import (
    PLATE_CELLS,
    PLATE_CONCEPTS,
    PLATE_OBSERVED,
    SITE_LABELS,
    SITE_PI,
    SITE_POTTS,
    Modality,
    ModelData,
)


def _near_uniform(site: str, modalities: Sequence[Modality]) -> str:
    """The refusal's hint for a fixed ``site``: the SpCoConfig variant whose Dirichlet prior
    holds it near uniform (the modality whose parameter ``site`` is names it, its concentration
    :func:`~spcopyro.config.concentration_name`: a field, or a key of ``concentrations``); none
    for labels."""
    name = next((m.name for m in modalities if m.parameter == site), None)
    if site == SITE_PI:
        variant = "prior='dirichlet', alpha=1e4"
    elif name is None:
        return ""
    elif (field := concentration_name(name)) != name:  # chi, beta
        variant = f"{field}=1e4"
    else:  # a further modality's: SpCoConfig.concentrations[name]
        variant = f"concentrations={{{name!r}: 1e4}}"
    return (
        f" (held near uniform, the variant is SpCoConfig({variant}): its Dirichlet prior "
        "concentrates there as the concentration grows)"
    )


def refuse_observed_latents(
    trace: pyro.poutine.Trace, names: Sequence[str], who: str, modalities: Sequence[Modality]
) -> None:
    """ValueError if any latent site of ``names`` is observed in ``trace`` (a model given as
    ``poutine.condition(model, {"pi": ...})``, a variant with pi known): SpCoGibbs and
    MeanFieldELBO (``who``) infer every latent site of :func:`~spcopyro.model.spcomapping_model`
    and cannot hold one fixed; they would draw the site anyway (the kernel) or score the guide's
    draws at the fixed value (the loss), silently. One message for both, with the variant that
    holds the site near uniform (``modalities``: ``data.modalities``, read only to say it)."""
    for name in names:
        if name in trace.nodes and trace.nodes[name]["is_observed"]:
            raise ValueError(
                f"the model's site {name!r} is observed (poutine.condition), but {who} infers "
                f"every latent site of spcomapping_model (pi, labels, each modality's table): "
                f"it cannot hold {name!r} fixed; pass the model without conditioning "
                f"{name!r}{_near_uniform(name, modalities)}"
            )


def refuse_foreign_sites(trace: pyro.poutine.Trace, data: ModelData, who: str) -> None:
    """ValueError naming the first sample or factor site of ``trace`` that
    :func:`~spcopyro.model.spcomapping_model` does not have (a further latent site such as a
    prior on gamma, a ``pyro.factor``): ``who`` samples or fits spcomapping_model's own
    conditionals, and such a model failed only the density comparison, with two numbers and no
    site named. Plates and ``pyro.deterministic`` sites (no density) are allowed."""
    known = {SITE_PI, SITE_LABELS, SITE_POTTS, PLATE_CONCEPTS, PLATE_CELLS, PLATE_OBSERVED}
    for modality in data.modalities:
        known.update((modality.name, modality.parameter))
    for name, site in trace.nodes.items():
        if site["type"] != "sample" or name in known or site["infer"].get("_deterministic"):
            continue
        if site_is_subsample(site):
            continue
        what = "observed site or factor" if site["is_observed"] else "latent site"
        raise ValueError(
            f"the model has a {what} {name!r} that spcomapping_model has not (its sites: "
            f"{sorted(known - {PLATE_CONCEPTS, PLATE_CELLS, PLATE_OBSERVED})}); {who} samples "
            "spcomapping_model's conditionals and cannot fit another model: change the model "
            "through SpCoConfig and ModelData.modalities, which it reads"
        )


class _ObservationsObserved(Messenger):
    """Raises :func:`require_observed` 's ValueError at the first observation site the model
    draws instead of observing (before the draw, which fails for real-valued counts)."""

    def __init__(self, data: ModelData, who: str) -> None:
        super().__init__()
        self.modalities = {m.name: m for m in data.modalities}
        self.cells = data.obs_cells
        self.who = who

    def _process_message(self, msg: dict) -> None:
        modality = self.modalities.get(msg["name"])
        if msg["type"] != "sample" or modality is None or msg["is_observed"]:
            return
        counts = modality.counts
        fractional = torch.nonzero(counts != counts.round())
        if fractional.shape[0]:
            row, column = (int(i) for i in fractional[0])
            why = (
                f"these counts are real-valued (tf-idf weights, image probabilities; row {row} "
                f"(free cell {int(self.cells[row])}), column {column} is "
                f"{float(counts[row, column])!r}), which no multinomial draws"
            )
        else:
            why = "it would score its own draws, not the data"
        raise ValueError(
            f"the model draws its observation site {msg['name']!r} instead of observing the "
            f"data's counts: poutine.uncondition(model) draws every observed site, and {why}. "
            f"{self.who} fits the posterior given the observed counts: pass the model itself "
            "(to draw observations from a fitted posterior, give poutine.uncondition(model) to "
            "pyro.infer.Predictive; whole counts only)"
        )


def require_observed(model: Callable, data: ModelData, who: str) -> Callable:
    """``model`` wrapped so that running it raises ValueError, naming ``who`` (the kernel or
    the loss), as soon as it draws one of ``data``'s observation sites instead of observing it
    (``poutine.uncondition(model)``): the draw itself failed for real-valued counts with
    "MultinomialCounts.sample needs non-negative whole total_count", and for whole counts the
    density check said only that the model's density differs."""
    return _ObservationsObserved(data, who)(model)
