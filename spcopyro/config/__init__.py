"""What a fit is configured by, in two layers that do not depend on each other.

* :class:`SpCoConfig`: the **model's** hyperparameters and variant switches (paper eqs. 1-10):
  everything :func:`~spcopyro.model.spcomapping_model` reads.
* :class:`~spcopyro.config.preparation.DataPreparation`: how observations become per-cell counts
  before the model sees them (image-feature scaling, word weighting, snapping of positions to
  free cells, the observation footprint), in its own module, :mod:`spcopyro.config.preparation`,
  whose names are importable from here too (``from spcopyro.config import DataPreparation``).

Inference options are per method and live beside the method (the Gibbs sampler's in
:class:`spcopyro.gibbs.options.GibbsOptions`). This package imports nothing of spcopyro but its
plumbing (``spcopyro._util``), so ``import spcopyro.model`` stays light
(no OpenCV, no yaml).

Presets (:func:`preset`) give both layers at once, as :class:`SpCoSettings`:

``paper-dp``
    The paper's Section 4.1 values for the weak-limit Dirichlet-process prior:
    alpha 1e8, beta 500, chi 1e4, gamma 4.0, L 120.
``paper-dirichlet``
    The paper's values for the finite Dirichlet prior: alpha 5e7, beta 100, chi 1e4, gamma 3.0,
    L = the known number of categories (pass ``num_concepts``).
``original-code``
    The released implementation's values: alpha 1e7, beta 0.1, chi 1.0, gamma 2.1, L 120,
    image features as floor(100 f).
``coarse`` (the default)
    Chosen on the public houses against the project's region truth, the synthetic houses and
    the open-plan houses together (issue 21; docs/real_houses.md, ``benchmarks/real_houses.py``):
    ``auto``'s model on a model grid of 0.25 m cells (``cell_size``: the Potts border cost per
    metre and the label-count prior no longer grow with the map's resolution), each utterance
    counted 10 times (``word_scaling``) and spread over a 0.75 m footprint, image histograms as
    probabilities (one observation each, not 100 draws), a fifth of each observation's weight
    spread over its geodesic Voronoi cell within its room, cut at 1 m doorways
    (``footprint_reach_share`` 0.2, ``footprint_reach_door_width`` 1.0: the rooms start's
    ``DEFAULT_DOOR_WIDTH``; docs/real_houses.md, "Reaching the Voronoi border"; since
    2026-12-06), and ``auto``'s inference settings
    plus region relabel moves in a fifth of the sweeps (:mod:`spcopyro.gibbs.region_move`: a
    room carried by two concepts merges; docs/real_houses.md, "Region relabel moves"). Its
    recommended inference settings add ``refine="auto"``: where the images tell the places
    apart, the fit goes on on the map's own cells (:mod:`spcopyro.fit.refine`; docs/real_houses.md,
    "Refinement on the map's cells").
``auto``
    What the ablation of issue #14 supports (docs/defaults.md, "The ablation, and the choice of
    `auto`"): the released code's emissions (beta 0.1, chi 1.0, floor(100 f): word and image
    tables the data can move, where the paper's beta 500 / chi 1e4 leave every concept's words
    uniform), gamma 3.0 (above the critical 2.48 for L = 120, so regions form), and, as
    recommended inference settings (:data:`PRESET_INFERENCE`), a start from a geometric room
    segmentation, split-merge moves in a fifth of the sweeps and the variation-of-information
    point estimate over the kept label maps as the reported map. The paper's presets stay as
    they are.

A note on gamma. The Potts prior over L labels on a square lattice has its critical coupling at
``ln(1 + sqrt(L))`` (2.48 for L = 120). Below it the MRF alone does not form regions: measured with
a port of the released code, ``original-code`` (gamma 2.1) keeps all 120 labels in patches of about
one cell after 1000 sweeps, while gamma 3.0 grows regions, slowed at walls and doorways. Above it,
regions appear by *coarsening*, slowly, over thousands of sweeps -- which is why sweep speed
matters -- toward the prior's equilibrium of one concept over the connected map, which the data
keep it from.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

from spcopyro._util.messages import setting
from spcopyro._util.number_checks import is_finite_number, is_int, is_number, is_positive_number
from spcopyro.config.preparation import (
    DEFAULT_SNAP_DISTANCE,
    RESOLVED_WORD_WEIGHTINGS,
    WORD_WEIGHTINGS,
    DataPreparation,
    FeatureScaling,
    FootprintKernel,
    WordWeighting,
    WordWeightingSetting,
    footprint_on,
    footprint_spreads,
    words_footprint_radius,
)

__all__ = [  # its own names and those it re-exports: preparation's and is_number
    "CONCENTRATION_FIELDS",
    "DEFAULT_PRESET",
    "DEFAULT_SNAP_DISTANCE",
    "DataPreparation",
    "FeatureScaling",
    "FootprintKernel",
    "HYPERPARAMETER_FIELDS",
    "IMAGES",
    "PRESETS",
    "PRESET_INFERENCE",
    "REACH_CUTS",
    "RESOLVED_WORD_WEIGHTINGS",
    "SpCoConfig",
    "SpCoSettings",
    "WORDS",
    "WORD_WEIGHTINGS",
    "WordWeighting",
    "WordWeightingSetting",
    "concentration_name",
    "footprint_on",
    "footprint_spreads",
    "is_number",
    "preset",
    "preset_inference",
    "words_footprint_radius",
]

IMAGES, WORDS = "images", "words"
"""The two modalities of the paper: place-class histograms of images (theta) and words (w)."""


CONCENTRATION_FIELDS: dict[str, str] = {IMAGES: "chi", WORDS: "beta"}
"""The :class:`SpCoConfig` field holding each of the paper's two modalities' Dirichlet
concentration: chi for images (eq. 3), beta for words (eq. 4). A further modality's is a key of
:attr:`SpCoConfig.concentrations`, its own name."""
HYPERPARAMETER_FIELDS: tuple[str, ...] = ("alpha", "gamma", *CONCENTRATION_FIELDS.values())
"""The hyperparameters that are fields of :class:`SpCoConfig`: ``("alpha", "gamma", "chi",
"beta")``; every other one is a further modality's concentration, named as the modality."""


def concentration_name(modality: str) -> str:
    """``chi`` for images, ``beta`` for words, else the modality's name: the name of a modality's
    Dirichlet concentration (:meth:`SpCoConfig.concentration`), a field of :class:`SpCoConfig`
    for the paper's two (:data:`CONCENTRATION_FIELDS`) and a key of
    :attr:`SpCoConfig.concentrations` for a further one."""
    return CONCENTRATION_FIELDS.get(modality, modality)


PRESETS: dict[str, dict[str, object]] = {
    "paper-dp": dict(
        prior="dp", alpha=1e8, beta=500.0, chi=1e4, gamma=4.0, num_concepts=120,
        feature_scaling="probability",
    ),
    "paper-dirichlet": dict(
        prior="dirichlet", alpha=5e7, beta=100.0, chi=1e4, gamma=3.0, num_concepts=None,
        feature_scaling="probability",
    ),
    "original-code": dict(
        prior="dp", alpha=1e7, beta=0.1, chi=1.0, gamma=2.1, num_concepts=120,
        feature_scaling="floor100",
    ),
    "auto": dict(
        prior="dp", alpha=1e7, beta=0.1, chi=1.0, gamma=3.0, num_concepts=120,
        feature_scaling="floor100",
    ),
    "coarse": dict(
        prior="dp", alpha=1e7, beta=0.1, chi=1.0, gamma=3.0, num_concepts=120,
        feature_scaling="probability", cell_size=0.25, word_scaling=10.0, footprint_radius=0.75,
        # the door width: spcopyro.maps.rooms.DEFAULT_DOOR_WIDTH, the rooms start's (plain here)
        footprint_reach_share=0.2, footprint_reach_door_width=1.0,
    ),
}  # fmt: skip
DEFAULT_PRESET = "coarse"

PRESET_INFERENCE: dict[str, dict[str, object]] = {
    "auto": dict(init="rooms", merge_moves=0.2, point_estimate="vi"),
    "coarse": dict(
        init="rooms", merge_moves=0.2, region_moves=0.2, point_estimate="vi", refine="auto"
    ),
}
"""The inference settings a preset recommends beside its model (names of ``fit_house`` keyword
arguments and :class:`~spcopyro.gibbs.options.GibbsOptions` fields, as plain values so that this
module stays free of the package): ``spcopyro fit`` applies them where the command line leaves
them unset; in Python pass them yourself (:func:`preset_inference`)."""


def preset_inference(name: str) -> dict[str, object]:
    """The inference settings :data:`PRESET_INFERENCE` recommends for preset ``name`` (empty
    for the paper's presets, which reproduce the paper: random start, single-site sweeps, the
    highest-log-joint state visited as the map)."""
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; choose one of {sorted(PRESETS)}")
    return dict(PRESET_INFERENCE.get(name, {}))


@dataclass(frozen=True)
class SpCoConfig:
    """Hyperparameters of SpCoMapping (paper eqs. 1-10) and the switches selecting a variant.

    Attributes:
        num_concepts: L, the number of concepts (the weak-limit upper bound for ``prior="dp"``).
        prior: ``"dp"``: pi ~ Dir(alpha/L, ..., alpha/L) (weak-limit DP, eq. 7);
            ``"dirichlet"``: pi ~ Dir(alpha, ..., alpha) (number of concepts known).
        alpha: concentration of the prior over pi.
        beta: symmetric Dirichlet concentration of each word distribution w_l (eq. 4).
        chi: symmetric Dirichlet concentration of each image-feature distribution theta_l (eq. 3).
        gamma: Potts MRF coupling between 4- (or 8-) neighbouring cells (eqs. 8-10), >= 0.
        connectivity: 4 (the released code's; the paper says only "the neighborhood pixels") or 8.
        use_images, use_words: switch the paper's two emission modalities on or off (a switched-off
            modality's distributions are still drawn, from their prior).
        concentrations: the symmetric Dirichlet concentration of every *further* modality (e.g.
            object-detection counts), by the modality's name; a mapping is accepted and stored as
            sorted ``(name, concentration)`` pairs. See :meth:`concentration`.
    """

    num_concepts: int = 120
    prior: Literal["dp", "dirichlet"] = "dp"
    alpha: float = 1e8
    beta: float = 500.0
    chi: float = 1e4
    gamma: float = 4.0
    connectivity: Literal[4, 8] = 4
    use_images: bool = True
    use_words: bool = True
    concentrations: tuple[tuple[str, float], ...] = ()

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ValueError:
            return ValueError(f"SpCoConfig.{name}={getattr(self, name)!r}: {why}")

        for name in ("num_concepts", "connectivity", "alpha", "beta", "chi", "gamma"):
            value = getattr(self, name)  # NumPy scalars (np.int64(5) "must be a positive integer")
            if isinstance(value, numbers.Integral) and not isinstance(value, int):
                object.__setattr__(self, name, int(value))
            elif isinstance(value, numbers.Real) and not isinstance(value, int | float):
                object.__setattr__(self, name, float(value))

        if not is_int(self.num_concepts) or self.num_concepts < 1:
            raise bad("num_concepts", "must be a positive integer")
        if self.prior not in ("dp", "dirichlet"):
            raise bad("prior", "must be 'dp' or 'dirichlet'")
        for name in ("alpha", "beta", "chi"):
            value = getattr(self, name)
            if not is_positive_number(value):
                raise bad(name, "must be a finite positive number")
        if not is_finite_number(self.gamma):
            raise bad("gamma", "must be a finite number")
        if self.gamma < 0:
            # The sampler's fast path writes exp(gamma n) = 1 + expm1(gamma n) as a mixture of
            # positive parts; an anti-ferromagnetic MRF is outside SpCoMapping's model anyway.
            raise bad("gamma", "must be >= 0 (neighbouring cells attract, never repel)")
        if self.connectivity in (4, 8) and self.gamma * self.connectivity > 700:
            # exp(gamma * n) for n up to D neighbours must stay finite in float64.
            raise bad("gamma", f"gamma * connectivity must be <= 700, got {self.gamma}")
        if not is_int(self.connectivity) or self.connectivity not in (4, 8):
            raise bad("connectivity", "must be 4 or 8")
        for name in ("use_images", "use_words"):  # "no" or "false" switched a modality on
            if not isinstance(getattr(self, name), bool):
                raise bad(name, "must be True or False")
        pairs = self.concentrations
        if isinstance(pairs, Mapping):
            pairs = tuple(pairs.items())
        try:
            pairs = tuple(sorted((str(name), value) for name, value in pairs))
        except (TypeError, ValueError):
            raise bad("concentrations", "must map modality names to numbers") from None
        for name, value in pairs:
            if name in (IMAGES, WORDS):
                raise bad("concentrations", f"{name!r} is set by chi / beta, not here")
            if not is_positive_number(value):
                raise bad("concentrations", f"{name!r} must be a finite positive number")
        if len({name for name, _ in pairs}) != len(pairs):
            raise bad("concentrations", "names a modality twice")
        object.__setattr__(self, "concentrations", tuple((n, float(v)) for n, v in pairs))

    @property
    def pi_concentration(self) -> float:
        """Each component of pi's Dirichlet concentration: alpha / L (DP) or alpha (Dirichlet)."""
        return self.alpha / self.num_concepts if self.prior == "dp" else self.alpha

    @property
    def critical_gamma(self) -> float:
        """The L-state Potts model's critical coupling ln(1 + sqrt(L)) on the square lattice
        with 4 neighbours (Potts 1952; Baxter 1973), ``connectivity=4``, the released code's.

        ValueError for ``connectivity=8``, which the model also supports: the square lattice
        with its diagonal neighbours (equal couplings) has no closed-form critical point (it
        orders at a lower coupling, every cell having twice the bonds: for L = 2, Monte Carlo
        estimates put it near 0.38 against 4 neighbours' 0.88), so the 4-neighbour value
        returned for it (as this did) was wrong, not a bound to compare gamma with. The
        low-gamma warning of a fit is given for 4 neighbours only."""
        if self.connectivity != 4:
            raise ValueError(
                f"critical_gamma ln(1 + sqrt(L)) is the 4-neighbour square lattice's; with "
                f"connectivity={self.connectivity} the Potts critical coupling has no closed "
                "form (it is lower: each cell has twice the bonds), so none is given"
            )
        return math.log1p(math.sqrt(self.num_concepts))

    def concentration(self, modality: str) -> float:
        """The symmetric Dirichlet concentration of a modality's distributions: chi for
        ``"images"`` (eq. 3), beta for ``"words"`` (eq. 4), else from :attr:`concentrations`."""
        if modality in CONCENTRATION_FIELDS:
            return float(getattr(self, CONCENTRATION_FIELDS[modality]))
        for name, value in self.concentrations:
            if name == modality:
                return value
        given = setting(f"SpCoConfig(concentrations={{{modality!r}: VALUE}})",
                        f"--concentration {modality}=VALUE")  # fmt: skip
        raise ValueError(
            f"no Dirichlet concentration for the further modality {modality!r}: set {given}"
        )

    def uses(self, modality: str) -> bool:
        """Whether a modality's observations enter the likelihood (``use_images`` /
        ``use_words``; further modalities are always used)."""
        if modality == IMAGES:
            return bool(self.use_images)
        if modality == WORDS:
            return bool(self.use_words)
        return True

    def replace(self, **changes: object) -> SpCoConfig:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def to_json(self) -> dict[str, object]:
        """The fields as JSON values (``concentrations`` as a name -> value object)."""
        values = dataclasses.asdict(self)
        values["concentrations"] = dict(self.concentrations)
        return values


REACH_CUTS: tuple[str, ...] = ("footprint_reach_radius", "footprint_reach_door_width")
"""The :class:`~spcopyro.config.preparation.DataPreparation` fields that cut the reach share's
Voronoi cells, refused where the share is 0. A share of 0 given over a preset's (``coarse``'s
0.2: :func:`preset`'s overrides, :meth:`SpCoSettings.replace`'s changes) drops the cuts the
caller did not choose (:meth:`SpCoSettings.chose`: the preset's 1 m door width): the share is
off, and its cuts with it; one the caller chose is still refused."""


@dataclass(frozen=True)
class SpCoSettings:
    """The model's hyperparameters and the data preparation they were chosen with (a preset).

    ``preset``: the name of the preset they came from (:func:`preset`; kept by
    :meth:`replace`, not part of equality), so that a fit can tell when it skips the inference
    settings that preset recommends (:func:`preset_inference`). ``chosen``: the names of the
    fields the caller set over it (:func:`preset`'s overrides, :meth:`replace`'s changes; not
    part of equality), so that a fit can name a value given that it replaces even where it is
    the preset's own (:func:`spcopyro.fit.refine.replaced_preparation`)."""

    model: SpCoConfig = SpCoConfig()
    data: DataPreparation = DataPreparation()
    preset: str | None = dataclasses.field(default=None, compare=False)
    chosen: frozenset[str] = dataclasses.field(default=frozenset(), compare=False, repr=False)

    def chose(self, field: str) -> bool:
        """Whether the caller chose the data preparation's ``field``: set it (``chosen``, even
        to the preset's own value), or its value differs from preset ``preset``'s (every field
        of settings made without one). The one rule of a share of 0's cuts (:data:`REACH_CUTS`)
        and of :func:`spcopyro.fit.refine.replaced_preparation`."""
        if self.preset not in PRESETS or field in self.chosen:
            return True
        own = PRESETS[self.preset].get(field, getattr(DataPreparation(), field))
        return getattr(self.data, field) != own

    def replace(self, **changes: object) -> SpCoSettings:
        """A copy with fields of either layer changed, each routed by its name; a share of 0
        drops the cuts of it the caller did not choose (:data:`REACH_CUTS`, :meth:`chose`)."""
        model_fields = {f.name for f in dataclasses.fields(SpCoConfig)}
        data_fields = {f.name for f in dataclasses.fields(DataPreparation)}
        unknown = set(changes) - model_fields - data_fields
        if unknown:
            raise ValueError(
                f"unknown settings {sorted(unknown)}: SpCoConfig has {sorted(model_fields)}, "
                f"DataPreparation has {sorted(data_fields)} (an inference method's options go "
                "to fit_house(options=...), e.g. GibbsOptions(anneal_sweeps=200))"
            )
        model = {k: v for k, v in changes.items() if k in model_fields}
        data = {k: v for k, v in changes.items() if k in data_fields}
        if "footprint_reach_share" in data and not data["footprint_reach_share"]:
            for cut in REACH_CUTS:  # a cut the caller did not choose goes with the share
                if cut not in changes and not self.chose(cut):
                    data[cut] = None
        return SpCoSettings(
            self.model.replace(**model) if model else self.model,
            self.data.replace(**data) if data else self.data,
            preset=self.preset,
            chosen=self.chosen | set(changes),
        )


def preset(name: str = DEFAULT_PRESET, **overrides: object) -> SpCoSettings:
    """The named preset (see the module docstring) with ``overrides`` applied to whichever layer
    (:class:`SpCoConfig` or :class:`~spcopyro.config.preparation.DataPreparation`) has a field
    of that name.

    ``paper-dirichlet`` needs ``num_concepts`` (the known number of categories).
    Overrides whose value is ``None`` are ignored, so CLI options can be passed straight through:
    ``preset("coarse", cell_size=None)`` keeps the preset's 0.25 m; ``cell_size="map"`` (or
    ``SpCoSettings.replace(cell_size=None)``, which sets what it is given) is the map's own cells.
    ``preset("coarse", footprint_reach_share=0)`` turns the reach share off and drops the
    preset's door width with it (:data:`REACH_CUTS`).
    """
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; choose one of {sorted(PRESETS)}")
    values = dict(PRESETS[name])
    given = {k: v for k, v in overrides.items() if v is not None}
    if values.get("num_concepts") is None:
        values["num_concepts"] = given.get("num_concepts")
    if values["num_concepts"] is None:
        raise ValueError(
            f"preset {name!r} needs num_concepts (the known number of place categories)"
        )
    data_fields = {f.name for f in dataclasses.fields(DataPreparation)}
    data = {k: values.pop(k) for k in list(values) if k in data_fields}
    own = SpCoSettings(SpCoConfig(**values), DataPreparation(**data), preset=name)
    if given.get("cell_size") == "map":  # the map's own cells, over a preset's cell size
        given["cell_size"] = None
    return own.replace(**given)  # chosen: the given; a share of 0 drops the preset's cuts
