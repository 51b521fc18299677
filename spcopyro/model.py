"""The SpCoMapping generative model as a Pyro program (paper eqs. 1-10).

The model is :func:`spcomapping_model`; :class:`ModelData` holds the map structure and the
per-cell observation counts it reads, built from an occupancy grid by :func:`make_model_data`.
Every free cell is one element of the ``cells`` plate, indexed in the grid's ``free_index`` order
(raster order of the map image); occupied and unknown cells are not in the model at all.
The model refuses inputs it cannot fit (:func:`check_model_data`); the refusals that the inference
tools run on a model they are given are in :mod:`spcopyro.model_checks`.
"""

from __future__ import annotations

import math
import sys
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import torch

from spcopyro.config import SpCoConfig

if TYPE_CHECKING:  # pragma: no cover
    import pyro.distributions as dist
    from pyro.infer import ELBO

    from spcopyro.data import CellCounts
    from spcopyro.data.footprint import SpreadSources
    from spcopyro.maps import OccupancyGrid

DTYPE = torch.float64  # Dirichlet draws with concentrations from 1e-3 to 1e8 need float64

# Site names, read by the Gibbs kernel (and checked against a trace of the model).
SITE_PI, SITE_THETA, SITE_W, SITE_LABELS = "pi", "theta", "w", "labels"
SITE_POTTS, SITE_IMAGES, SITE_WORDS = "potts", "images", "words"
PLATE_CONCEPTS, PLATE_CELLS, PLATE_OBSERVED = "concepts", "cells", "observed_cells"


class Modality(NamedTuple):
    """One emission modality: what the observed cells hold of it, and the model's site names.

    Every concept l has a distribution over the modality's K_m items, drawn from a symmetric
    Dirichlet (concentration :meth:`SpCoConfig.concentration(name)
    <spcopyro.config.SpCoConfig.concentration>`), and an observed cell's counts are multinomial
    under its concept's distribution. The paper's two modalities are ``images`` (theta, eqs. 3, 5)
    and ``words`` (w, eqs. 4, 6); any further one (sounds, object detections, ...) is one more.
    """

    name: str
    """The observation site (``"images"``, ``"words"``, or the further modality's name)."""
    parameter: str
    """The site of the per-concept distributions ``[L, K_m]`` (``"theta"``, ``"w"``, ...)."""
    counts: torch.Tensor
    """[M, K_m] float64: the modality's counts summed per observed cell (may be real-valued)."""
    spread: FactoredCounts | None = None
    """With a footprint, ``counts`` in factored form (:meth:`factored`); None otherwise."""

    def factored(self) -> SpreadSources | None:
        """``counts`` as a product of the footprints' weights and counts
        (:class:`~spcopyro.data.footprint.SpreadSources`), for kernels whose products pay less
        with it; None without one, and once ``counts`` is not the tensor it was made for
        (replaced by ``_replace`` or changed in place), so a stale product is never used."""
        spread = self.spread
        if spread is None or spread.of is not self.counts or spread.version != self.counts._version:
            return None
        return spread.sources


class FactoredCounts(NamedTuple):
    """A :class:`~spcopyro.data.footprint.SpreadSources` bound to the counts tensor it equals."""

    sources: SpreadSources
    of: torch.Tensor  # the Modality.counts tensor, by identity
    version: int  # of._version when bound: an in-place change unbinds it


def parameter_site(modality: str) -> str:
    """The site name of a modality's per-concept distributions: ``theta`` for images, ``w`` for
    words (the paper's names), ``<name>_probs`` for a further modality."""
    return {SITE_IMAGES: SITE_THETA, SITE_WORDS: SITE_W}.get(modality, f"{modality}_probs")


class ModelData(NamedTuple):
    """What the model conditions on: N free cells, M of them observed, one count matrix per
    modality (images ``[M, K]`` and words ``[M, V]`` first, then any further modality)."""

    num_free: int
    """N, the number of free cells (the ``cells`` plate)."""
    neighbours: torch.Tensor
    """[N, D] int64: free index of each cell's D = 4 (or 8) neighbours, -1 where none is free."""
    pairs: torch.Tensor
    """[P, 2] int64: every unordered pair of neighbouring free cells once (a < b)."""
    colours: tuple[torch.Tensor, ...]
    """Graph colouring: int64 free indices of each colour class (2 for D=4, 4 for D=8)."""
    obs_cells: torch.Tensor
    """[M] int64: free index of each cell holding observations (ascending)."""
    modalities: tuple[Modality, ...]
    """The emission modalities, ``images`` and ``words`` first; their count rows follow
    ``obs_cells``."""

    def modality(self, name: str) -> Modality:
        """The modality called ``name`` (KeyError naming the known ones if there is none)."""
        for modality in self.modalities:
            if modality.name == name:
                return modality
        known = [m.name for m in self.modalities]
        raise KeyError(f"ModelData has no modality {name!r}; it has {known}")

    def with_counts(self, name: str, counts: torch.Tensor) -> ModelData:
        """A copy with the counts of modality ``name`` replaced."""
        self.modality(name)  # raises for an unknown name
        return self._replace(
            modalities=tuple(
                m._replace(counts=counts, spread=None) if m.name == name else m
                for m in self.modalities
            )
        )

    @property
    def image_counts(self) -> torch.Tensor:
        """[M, K] the image-feature counts (the ``images`` modality)."""
        return self.modality(SITE_IMAGES).counts

    @property
    def word_counts(self) -> torch.Tensor:
        """[M, V] the word counts or tf-idf weights (the ``words`` modality)."""
        return self.modality(SITE_WORDS).counts

    @property
    def num_feature_classes(self) -> int:
        return self.image_counts.shape[-1]

    @property
    def vocabulary_size(self) -> int:
        return self.word_counts.shape[-1]

    def observation_rows(self) -> torch.Tensor:
        """[N] int64: each free cell's row in ``obs_cells`` and the count tensors, -1 if none."""
        rows = torch.full((self.num_free,), -1, dtype=torch.long)
        rows[self.obs_cells] = torch.arange(self.obs_cells.shape[0])
        return rows


def make_model_data(grid: OccupancyGrid, counts: CellCounts, connectivity: int = 4) -> ModelData:
    """The model's tensors from a grid and its :class:`~spcopyro.data.CellCounts` (images and
    words, then each further modality of ``counts.modalities``, if it has any)."""
    if counts.num_free != grid.num_free:
        raise ValueError(
            f"CellCounts were made for a map with {counts.num_free} free cells, "
            f"this map has {grid.num_free}"
        )

    def as_long(a: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.ascontiguousarray(a), dtype=torch.long)

    named = [(SITE_IMAGES, counts.image_counts), (SITE_WORDS, counts.word_counts)]
    named += [(m.name, m.counts) for m in getattr(counts, "modalities", ())]
    names = [name for name, _ in named]
    if len(set(names)) != len(names):
        raise ValueError(f"modality names must be distinct, got {names}")
    spread = getattr(counts, "spread", {})

    def modality(name: str, values: np.ndarray) -> Modality:
        tensor = torch.as_tensor(values, dtype=DTYPE)
        factored = spread.get(name)
        if factored is None or factored.shape != tuple(tensor.shape):
            return Modality(name, parameter_site(name), tensor)
        bound = FactoredCounts(factored, tensor, tensor._version)
        return Modality(name, parameter_site(name), tensor, bound)

    return ModelData(
        num_free=int(grid.num_free),
        neighbours=as_long(grid.neighbour_table(connectivity)),
        pairs=as_long(grid.neighbour_pairs(connectivity)),
        colours=tuple(as_long(c) for c in grid.colour_classes(connectivity)),
        obs_cells=as_long(counts.cells),
        modalities=tuple(modality(name, values) for name, values in named),
    )


def check_model_data(data: ModelData, config: SpCoConfig | None = None) -> None:
    """Refuse counts that every inference method would turn into NaN or a bare shape error
    deep inside (a NaN count gave a NaN ELBO under CAVI and "gamma concentration must be finite
    and positive" under Gibbs): ``obs_cells`` ``[M]`` free indices in ``[0, N)``, and each
    modality's counts an ``[M, K_m]`` float64 tensor, finite and >= 0 (a multinomial's counts,
    possibly real-valued: :class:`~spcopyro.distributions.MultinomialCounts`). Raises
    ValueError naming the modality, the entry and its value.

    With ``config``: TypeError unless it is an :class:`~spcopyro.config.SpCoConfig` (an
    ``SpCoSettings`` gave "has no attribute 'num_concepts'"), and ValueError unless its
    ``connectivity`` is the one ``data``'s neighbour table was made with (data made for 4
    neighbours under an 8-neighbour config were fitted with 4, silently), nor while its
    ``concentrations`` name a modality the data have not (fitted without it, silently)."""
    if not isinstance(data, ModelData):
        raise TypeError(
            f"data must be a ModelData (spcopyro.model.make_model_data, or "
            f"spcopyro.fit.house.prepare_model_data), got {type(data).__name__}"
        )
    if config is not None:
        check_config(config)
        if data.neighbours.dim() == 2 and data.neighbours.shape[1] != config.connectivity:
            raise ValueError(
                f"the data's neighbour table has {data.neighbours.shape[1]} neighbours a cell "
                f"but config.connectivity is {config.connectivity}: make the data with "
                f"prepare_model_data(house, settings.replace(connectivity="
                f"{config.connectivity})) and pass its settings.model, or with "
                f"make_model_data(grid, counts, connectivity={config.connectivity})"
            )
        check_concentration_names(data, config)
    _check_site_names(data)
    N, cells = data.num_free, data.obs_cells
    if cells.dim() != 1 or (cells.numel() and not 0 <= int(cells.min()) <= int(cells.max()) < N):
        raise ValueError(f"ModelData.obs_cells must be [M] free indices in [0, {N})")
    M = cells.shape[0]
    for name, counts in ((m.name, m.counts) for m in data.modalities):
        if counts.dim() != 2 or counts.shape[0] != M:
            raise ValueError(
                f"the counts of modality {name!r} have shape {tuple(counts.shape)}, expected "
                f"({M}, K): one row per observed cell of ModelData.obs_cells"
            )
        if counts.dtype != DTYPE:
            raise ValueError(f"the counts of modality {name!r} must be {DTYPE}, got "
                             f"{counts.dtype}: convert them with counts.double()")  # fmt: skip
        if counts.shape[1] == 0 and name != SITE_WORDS:  # a Dirichlet over no items: unnamed
            raise ValueError(
                f"modality {name!r} has no items (its counts are [{M}, 0]): each concept's "
                "distribution over them needs at least one; leave the modality out"
            )
        if not counts.numel() or (counts.min() >= 0 and torch.isfinite(counts.sum())):
            continue  # two reductions: a NaN fails the min, an inf the sum (the model's every call)
        wrong = ~torch.isfinite(counts) | (counts < 0)  # [M, K_m]
        if wrong.any():
            row, column = (int(i) for i in torch.nonzero(wrong)[0])
            raise ValueError(
                f"the counts of modality {name!r} must be finite and >= 0; row {row} (free "
                f"cell {int(cells[row])}), column {column} is {float(counts[row, column])}"
            )


def check_concentration_names(
    data: ModelData,
    config: SpCoConfig,
    holder: str = "the data have",
    fix: str = "add it to ModelData.modalities (Modality(name, parameter_site(name), counts "
    "[M, K_m])) or correct the name",
) -> None:
    """ValueError where ``config.concentrations`` names a modality the data have not (a
    misspelt name, or data made before the modality was added): the model, the kernel and the
    guides fitted the data without it, silently. One test, worded by its caller: ``holder``
    what lacks the modality, ``fix`` the way out (``prepare_model_data``: a house and its
    ``modality_<name>.csv``)."""
    names = {m.name for m in data.modalities}
    unused = [name for name, _ in config.concentrations if name not in names]
    if unused:
        further = [m.name for m in data.modalities if m.name not in (SITE_IMAGES, SITE_WORDS)]
        raise ValueError(
            f"SpCoConfig.concentrations names {unused}, but {holder} no such modality "
            f"(further modalities: {further or 'none'}): {fix}"
        )


def _check_site_names(data: ModelData) -> None:
    """ValueError unless every modality's observation and parameter sites have names of their
    own: a further modality called ``labels``, ``theta``, ``cells``, ... (or whose parameter
    site is its own name) failed in Pyro with "Multiple sample sites named ..." under every
    Pyro tool, naming neither the modality nor the fix."""
    taken = {name: "a site of the model" for name in (SITE_PI, SITE_LABELS, SITE_POTTS)}
    taken.update((name, "a plate of the model") for name in (PLATE_CONCEPTS, PLATE_CELLS,
                                                            PLATE_OBSERVED))  # fmt: skip
    for modality in data.modalities:
        for kind, name in (("name", modality.name), ("parameter site", modality.parameter)):
            if name in taken:
                fix = (
                    "give the modality another name"
                    if kind == "name"
                    else f"make it Modality(name, parameter_site(name), counts): "
                    f"{parameter_site(modality.name)!r}"
                )
                raise ValueError(
                    f"modality {modality.name!r}: its {kind} {name!r} is already {taken[name]}; "
                    f"{fix}"
                )
            taken[name] = f"a site of modality {modality.name!r}"


def check_config(config: object) -> None:
    """TypeError unless ``config`` is an :class:`~spcopyro.config.SpCoConfig` (an
    ``SpCoSettings``' model part is ``settings.model``)."""
    if isinstance(config, SpCoConfig):
        return
    hint = " (pass settings.model)" if hasattr(config, "model") and hasattr(config, "data") else ""
    raise TypeError(f"config must be an SpCoConfig{hint}, got {type(config).__name__}")


def potts_agreements(labels: torch.Tensor, pairs: torch.Tensor) -> torch.Tensor:
    """E(C) = sum over neighbour pairs (a, b) of delta(C_a, C_b), the Potts MRF's statistic.

    ``labels`` is ``[..., N]``; the result is ``[...]`` (float64).
    """
    same = labels[..., pairs[:, 0]] == labels[..., pairs[:, 1]]  # [..., P]
    return same.sum(-1).to(DTYPE)


def _check_site_shape(site: str, value: torch.Tensor, expected: tuple[int, ...]) -> None:
    """ValueError unless a drawn or given (``Predictive``'s posterior samples, a guide's) value
    of ``site`` has the model's shape: samples of another L or vocabulary were used silently."""
    if tuple(value.shape[-len(expected) :]) != expected:
        raise ValueError(
            f"the value of site {site!r} has shape {tuple(value.shape)}, but these data and "
            f"config make it {expected} (L = num_concepts, then the modality's classes): were "
            "the samples drawn for other data or another num_concepts?"
        )


def _check_label_range(labels: torch.Tensor, L: int) -> None:
    """ValueError unless given labels (``poutine.condition``, ``Predictive``'s posterior samples)
    are concept ids in [0, L): labels of a fit with a larger L failed with a bare IndexError in
    the observation sites, and a negative one picked a concept from the end silently."""
    # labels: [N]; two reductions, O(N)
    if not labels.numel() or (int(labels.min()) >= 0 and int(labels.max()) < L):
        return
    cell = int(torch.nonzero((labels < 0) | (labels >= L))[0])
    raise ValueError(
        f"the labels must be concept ids in [0, {L}) (L = config.num_concepts), but free cell "
        f"{cell}'s is {int(labels[cell])} (values in [{int(labels.min())}, "
        f"{int(labels.max())}]): were the labels drawn for another num_concepts?"
    )


def calling_elbo() -> ELBO | None:
    """The innermost :class:`pyro.infer.ELBO` whose method is running the caller, if any: an
    ELBO's ``loss``, ``loss_and_grads`` or ``differentiable_loss`` is on the call stack whenever
    it runs a guide (``Predictive`` and a plain call run none). The walk starts at the caller's
    caller (the model, or the guide's ``forward``)."""
    from pyro.infer import ELBO

    frame = sys._getframe(2)
    while frame is not None:
        owner = frame.f_locals.get("self")
        if isinstance(owner, ELBO):
            return owner
        frame = frame.f_back
    return None


def _refuse_prior_labels_under_an_elbo() -> None:
    """ValueError where a Pyro ELBO replays a guide that has no ``labels`` site (an autoguide
    of the globals, ``AutoNormal(poutine.block(model, hide=["labels"]))``): the model drew the
    labels from Categorical(pi) in every step, without the Potts factor, and Trace_ELBO took
    steps on that estimate with no more than Pyro's UserWarning 'Found vars in model but not
    guide'. Cheap unless so: a look at Pyro's handler stack, the call stack only then."""
    from pyro.poutine.condition_messenger import ConditionMessenger
    from pyro.poutine.replay_messenger import ReplayMessenger
    from pyro.poutine.runtime import _PYRO_STACK

    replayed = [m.trace for m in _PYRO_STACK if isinstance(m, ReplayMessenger)]
    if not any(t is not None and SITE_PI in t and SITE_LABELS not in t for t in replayed):
        return
    for handler in _PYRO_STACK:  # labels given by poutine.condition: not drawn
        if isinstance(handler, ConditionMessenger) and SITE_LABELS in (handler.data or {}):
            return
    loss = calling_elbo()  # from spcomapping_model's frame
    if loss is None:
        return
    raise ValueError(
        f"{type(loss).__name__} runs a guide with no 'labels' site (an autoguide of the globals, "
        "poutine.block(model, hide=['labels'])?), so spcomapping_model draws the labels from "
        "Categorical(pi) in every step, without the Potts factor: the loss fits nothing of the "
        "map. Fit spcopyro.guides.MeanFieldGuide with MeanFieldELBO under SVI (q(C) in closed "
        "form), or sample the labels with spcopyro.gibbs.SpCoGibbs under MCMC"
    )


def _table_prior(modality: Modality, config: SpCoConfig, L: int) -> dist.Distribution:
    """Each concept's distribution over the modality's K_m items: the symmetric Dirichlet of
    eqs. (3), (4); over no items (the words of a house where none was heard, V = 0) the
    Dirichlet's simplex is the one empty vector, so the draw is that point (log density 0)."""
    import pyro.distributions as dist

    K = modality.counts.shape[-1]
    if K == 0:  # Pyro's Dirichlet refuses an empty simplex
        return dist.Delta(torch.zeros((L, 0), dtype=DTYPE), event_dim=1)
    return dist.Dirichlet(torch.full((K,), config.concentration(modality.name), dtype=DTYPE))


def spcomapping_model(data: ModelData, config: SpCoConfig) -> None:
    r"""SpCoMapping (Katsumata et al., 2019), eqs. (1)-(10); its conditionals are eqs. (13)-(17).

    .. math::

        \pi &\sim \mathrm{Dir}(\alpha/L, \dots, \alpha/L)
            \;\text{(weak-limit DP, eqs. 1, 7) or}\; \mathrm{Dir}(\alpha, \dots, \alpha) \\
        \theta_l &\sim \mathrm{Dir}(\chi), \quad w_l \sim \mathrm{Dir}(\beta),
            \qquad l = 1..L \quad\text{(eqs. 3, 4)} \\
        p(C \mid \pi, \gamma) &\propto \prod_{ij} \mathrm{Mult}(C_{ij} \mid \pi)\,
            \exp\Big(\gamma \sum_{(ij, i'j') \in \mathcal{N}} \delta(C_{ij}, C_{i'j'})\Big)
            \quad\text{(eqs. 2, 8-10)} \\
        f_t &\sim \mathrm{Mult}(\theta_{C_{\mathrm{convert}(x_t)}}), \quad
        S_t \sim \mathrm{Mult}(w_{C_{\mathrm{convert}(x_t)}}) \quad\text{(eqs. 5, 6, 11)}

    **The density.** As in the paper, the Potts normaliser :math:`Z(\pi, \gamma)` is left out: the
    ``labels`` site scores :math:`\sum_{ij} \log \pi_{C_{ij}}` and the ``potts`` factor adds
    :math:`\gamma E(C)`. So this model's log density is the *unnormalised* joint

    .. math::

        \log p^*(\pi, \theta, w, C, f, S) = \log \mathrm{Dir}(\pi)
          + \sum_l \log \mathrm{Dir}(\theta_l)
          + \sum_l \log \mathrm{Dir}(w_l) + \sum_{ij} \log \pi_{C_{ij}} + \gamma E(C)
          + \sum_{\text{observed cells}} \log \mathrm{Mult}(f, S \mid \theta_C, w_C),

    whose full conditionals are exactly Algorithm 1's: eq. (13) for each cell label and the
    conjugate Dirichlet draws of eqs. (14)-(17). The joint of :math:`(\pi, C)` it defines,
    :math:`\mathrm{Dir}(\pi) \prod \pi_{C_{ij}} e^{\gamma E(C)}`, is still proper (finite label
    space), which is what the joint-distribution tests sample from.

    Observations enter per observed cell: the features and words of all observations that fall
    in one cell are summed (a multinomial's counts are sufficient), so the model reads one
    ``[M, K_m]`` count matrix per modality (``data.modalities``: images and words, and any
    further modality, each with its own Dirichlet concentration and site names). Counts may be
    real-valued (probabilities, tf-idf weights):
    see :class:`~spcopyro.distributions.MultinomialCounts`. The observation footprint
    (``DataPreparation.footprint_radius``, :mod:`spcopyro.data.footprint`) is such counts: each
    observation spread over the cells around it with weights w_tc summing to one, so that this
    density is, up to a constant, the tempered product prod_t prod_c p(x_t | C_c)^{w_tc}.

    **Running it forward.** The model's sites come in this order: pi (eqs. 1, 7); theta_l and
    w_l of every concept (and each further modality's distributions) from their Dirichlets
    (eqs. 3, 4), which do not depend on the labels; the labels, each cell independently from
    Mult(pi) (the Mult(C | pi) term of eq. 10); the ``potts`` factor gamma E(C) (eqs. 8-10); and
    last each observed cell's counts from its concept's theta and w (eqs. 5, 6). Under
    :func:`pyro.poutine.uncondition` it draws them all in that order, but its ``labels`` draw
    ignores the Potts term (a factor cannot be sampled). A draw of the whole prior, MRF included,
    is :func:`spcopyro.simulate.sample_prior_world`, in the same order: pi from its Dirichlet
    (eqs. 1, 7), then theta and w from theirs (eqs. 3, 4), before and independently of the
    labels; then the labels, drawn each from Mult(pi) and moved by ``sweeps`` label-only Gibbs
    sweeps of the kernel (eq. 13 without its emission terms: the exact conditional of the Potts
    prior of eqs. 2, 8-10 given pi); then this model, conditioned on pi, theta, w and those
    labels, draws only the emissions f and S (eqs. 5, 6), each observed cell keeping its totals.

    Complexity: one evaluation is O(N + P + (M + L) sum_m K_m).

    Args:
        data: the map structure and per-cell counts (:func:`make_model_data`).
        config: hyperparameters and variant switches.

    **References:** A. Katsumata, W. Hashimoto, Y. Hagiwara, T. Taniguchi, "Semantic Mapping Based
    on Spatial Concepts for Grounding Words Related to Places in Daily Environments", Frontiers in
    Robotics and AI 6:31, 2019.
    """
    import pyro  # here: the sampler and the other methods use this module's data without Pyro
    import pyro.distributions as dist

    from spcopyro.distributions import MultinomialCounts

    check_model_data(data, config)
    L = config.num_concepts

    pi = pyro.sample(
        SITE_PI, dist.Dirichlet(torch.full((L,), config.pi_concentration, dtype=DTYPE))
    )
    _check_site_shape(SITE_PI, pi, (L,))
    if math.prod(pi.shape[:-1]) > 1:  # Predictive(parallel=True) hands a batch (a guide: [1, L])
        raise ValueError(
            f"spcomapping_model takes one sample of pi at a time, got a batch of shape "
            f"{tuple(pi.shape)} (its labels are indexed per cell and its Potts factor is not "
            "batched): use pyro.infer.Predictive(..., parallel=False)"
        )
    with pyro.plate(PLATE_CONCEPTS, L, dim=-1):
        parameters = [
            pyro.sample(modality.parameter, _table_prior(modality, config, L))
            for modality in data.modalities
        ]  # theta: [L, K], w: [L, V], ...: [L, K_m]
    for modality, probs in zip(data.modalities, parameters, strict=True):
        _check_site_shape(modality.parameter, probs, (L, modality.counts.shape[-1]))

    with pyro.plate(PLATE_CELLS, data.num_free, dim=-1):
        labels = pyro.sample(SITE_LABELS, dist.Categorical(pi))  # [N]
    if tuple(labels.shape) != (data.num_free,):  # NUTS / TraceEnum_ELBO enumerate: [L, 1]
        raise ValueError(
            f"the labels have shape {tuple(labels.shape)}, not ({data.num_free},) (N free "
            "cells): spcomapping_model's labels cannot be enumerated or batched (the Potts "
            "factor couples every cell; NUTS, HMC, TraceEnum_ELBO and infer_discrete "
            "enumerate them): sample them with spcopyro.gibbs.SpCoGibbs under MCMC, or fit "
            "spcopyro.guides.MeanFieldGuide with MeanFieldELBO under SVI"
        )
    if labels.dtype.is_floating_point or labels.dtype.is_complex:  # conditioned on floats
        raise ValueError(
            f"the labels must be integer concept ids (torch.long), got {labels.dtype}: "
            "condition the model on labels.long()"
        )
    _check_label_range(labels, L)
    _refuse_prior_labels_under_an_elbo()
    pyro.factor(SITE_POTTS, config.gamma * potts_agreements(labels, data.pairs))

    if data.obs_cells.shape[0] == 0:  # a map with no observations yet: the prior alone
        return  # (Pyro refuses a plate of size 0)
    observed_labels = labels[data.obs_cells]  # [M]
    with pyro.plate(PLATE_OBSERVED, data.obs_cells.shape[0], dim=-1):
        for modality, probs in zip(data.modalities, parameters, strict=True):
            if config.uses(modality.name) and modality.counts.shape[-1]:  # no items: nothing seen
                pyro.sample(
                    modality.name,
                    MultinomialCounts(probs[observed_labels], modality.counts.sum(-1)),
                    obs=modality.counts,
                )
