r"""Speck concepts and how much of the posterior holds them.

A speck (:func:`~spcopyro.results.concept_words.is_speck`) is a concept in use on fewer than
:data:`~spcopyro.results.concept_words.SPECK_SHARE` of the free cells and under
:data:`~spcopyro.results.concept_words.SPECK_AREA` square metres where fewer than
:data:`~spcopyro.results.concept_words.SPECK_WORDS` words were heard (no word at all until
the footprint's reach share gave nearly every cell of a room a little). It is counted among
the concepts in use, but it is no place. Since 2026-12-06 the point estimates ``vi`` and
``binder`` have none (unless every concept is one): their cells are joined to other
concepts (:mod:`~spcopyro.results.speck_join`; on the README's fit of the embedded house its six
one-cell specks, for 0.00078 nats of expected variation of information, 0.1550 -> 0.1558; those
cells agree with the concept they joined in 34-46 % of the kept samples, which agreement.png
shows). The specks that follow are those of ``vi-specks`` (the same estimate with its specks,
``vi`` before 2026-12-06) and of the highest-log-joint state visited. On the README's fit of the
embedded house (``spcopyro fit --out DIR``, 2026-12-05, with the 1 m footprint, the default
before 2026-12-06) the four one-cell specks sit on unobserved cells, two in doorways between two
rooms and two in convex corners with two free neighbours, and their cells took the speck's
concept in 0.28, 0.30, 0.50 and 0.56 of the 50 kept samples (a room's cells: 1.00). Every kept
sample holds ~40 labels, ~39 of them one-cell droplets that form and dissolve; the
variation-of-information search keeps a cell apart where its co-clustering probability with
every neighbouring concept is below about one half (0.30-0.48 at these four: merging any of them
into a neighbour raises the expected loss by 6e-5 to 6e-4 nats of 0.1505). With the 0.75 m
footprint (the default since 2026-12-06) the same fit has six specks in ``vi-specks``, held in
28-56 % of the kept samples (median 38 %; docs/defaults.md).
Under a preset that reports the highest-log-joint state visited (``original-code``, ``paper-dp``)
the specks are that one state's droplets: 48 of them on the embedded house under
``--preset original-code --gamma 3 --sweeps 1000``, held by their cells in a median 6 % of the
kept samples (0-40 %).

:func:`speck_support` is that share per speck, so that the listing and the figures can say how
much of the posterior a speck has rather than count it as a place.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from spcopyro._util.messages import plural
from spcopyro.results.concept_words import is_speck


class ResultView(Protocol):
    """What these functions read of a :class:`~spcopyro.results.result.SpCoResult`, stated as
    a protocol so that this module need not import the result's (which imports it to write
    ``concepts.json``: no import cycle, tests/test_architecture.py)."""

    labels: Any  # [N] the reported concept of each free cell
    agreement: Any  # [N] or None
    marginals: Any  # [N, L] or None
    inference: dict[str, Any]
    grid: Any

    def concept_sizes(self) -> np.ndarray: ...  # [L]

    def concepts_in_use(self) -> np.ndarray: ...  # [K] concept ids

    def heard(self, concept: int) -> float | None: ...


__all__ = ["in_use_text", "speck_concepts", "speck_support", "support_text", "with_speck_fields"]


def speck_concepts(result: ResultView) -> list[int]:
    """The specks among the concepts in use, largest first (as
    :meth:`~spcopyro.results.result.SpCoResult.concepts_in_use` orders them)."""
    sizes = result.concept_sizes()  # [L]
    num_free, cell_area = result.grid.num_free, result.grid.cell_area  # the labels' grid
    return [int(c) for c in result.concepts_in_use()
            if is_speck(int(sizes[c]), result.heard(int(c)), num_free, cell_area)]  # fmt: skip


def in_use_text(result: ResultView) -> str:
    """``"10 concepts in use (4 of them specks)"``: the count ``fit`` prints and the semantic map's
    title gives, saying how many of the concepts are specks rather than places (it counted a
    one-cell speck like a room: "10 concepts in use" over a house of six rooms)."""
    text = f"{plural(len(result.concepts_in_use()), 'concept')} in use"
    specks = len(speck_concepts(result))
    if specks:
        text += f" ({specks} of them {'a speck' if specks == 1 else 'specks'})"
    return text


def _per_cell(result: ResultView) -> np.ndarray | None:
    """``[N]`` p(C_i = the reported concept of cell i): the agreement, else the marginals."""
    if result.agreement is not None:
        return np.asarray(result.agreement, dtype=np.float64)
    if result.marginals is None:
        return None
    labels = np.asarray(result.labels)  # [N]
    marginals = np.asarray(result.marginals)  # [N, L]
    return marginals[np.arange(labels.shape[0]), labels].astype(np.float64)


def speck_support(result: ResultView, concepts: list[int]) -> np.ndarray | None:
    r"""``[len(concepts)]`` per concept, the mean over its cells of :math:`p(C_i = c)`, the
    posterior probability that the cell holds the concept: the result's agreement (the share of
    kept samples whose matched label is the reported one,
    :func:`~spcopyro.results.point_estimate.agreement_probability`) where it has one, else its
    marginals (aligned sample frequencies, or a variational q). None when it has neither."""
    per_cell = _per_cell(result)
    return None if per_cell is None else _support(per_cell, np.asarray(result.labels), concepts)


def _support(per_cell: np.ndarray, labels: np.ndarray, concepts: list[int]) -> np.ndarray:
    """:func:`speck_support` of the per-cell probabilities ``per_cell`` [N] and ``labels`` [N]."""
    return np.array([per_cell[labels == c].mean() for c in concepts], dtype=np.float64)


def support_text(result: ResultView, concepts: list[int]) -> str | None:
    """How much of the posterior holds these specks, beside the other concepts' cells, for the
    listing and the legend, e.g. ``"their cells took them in 28-56% of the 50 kept samples
    (agreement.npy), the other concepts' cells 99%"``; None without per-cell probabilities or
    specks."""
    per_cell = _per_cell(result) if concepts else None
    if per_cell is None:
        return None
    labels = np.asarray(result.labels)  # [N]
    support = _support(per_cell, labels, concepts)
    low, high = round(100 * support.min()), round(100 * support.max())
    share = f"{low}%" if low == high else f"{low}-{high}%"
    if len(concepts) > 4 and high - low >= 10:
        share += f" (median {round(100 * float(np.median(support)))}%)"
    others = ~np.isin(labels, concepts)  # [N] cells of the other concepts
    rest = ""
    if others.any():
        rest = f", the other concepts' cells {round(100 * per_cell[others].mean())}%"
    samples = result.inference.get("marginal_samples")
    them = "it" if len(concepts) == 1 else "them"
    if len(concepts) > 1:
        cells = "their cells"
    else:
        cells = "its cells" if int(np.sum(~others)) > 1 else "its cell"
    if isinstance(samples, int | np.integer) and samples > 0:
        where = "agreement.npy" if result.agreement is not None else "the marginals"
        return f"{cells} took {them} in {share} of the {int(samples)} kept samples ({where}){rest}"
    return f"{cells} hold {them} with probability {share} (the method's marginals){rest}"


def with_speck_fields(result: ResultView, concepts: list[dict[str, object]]) -> list[dict]:
    """``concepts`` (:meth:`~spcopyro.results.result.SpCoResult.concepts`) as ``concepts.json``
    writes them: each entry with ``speck`` (bool: a speck, not a place) and ``support`` (the mean
    over its cells of p(C_i = concept), :func:`speck_support`; None without per-cell
    probabilities), so that a reader of the file can tell a one-cell speck from a room."""
    ids = [int(c["concept"]) for c in concepts]  # type: ignore[call-overload]
    specks = set(speck_concepts(result))
    support = speck_support(result, ids)
    return [
        {**c, "speck": i in specks, "support": None if support is None else float(support[k])}
        for k, (i, c) in enumerate(zip(ids, concepts, strict=True))
    ]
