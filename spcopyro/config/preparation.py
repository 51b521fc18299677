"""How observations become the per-cell counts the model reads: :class:`DataPreparation`
(image-feature scaling, word weighting, snapping of positions to free cells, the observation
footprint and its reach share), its field types and values, and the footprint's tests
(:func:`footprint_on`, :func:`footprint_spreads`, :func:`words_footprint_radius`).

One of a fit's two layers of settings (:mod:`spcopyro.config`, beside the model's
:class:`~spcopyro.config.SpCoConfig`; a preset gives both, as
:class:`~spcopyro.config.SpCoSettings`). Every name here is also importable from
:mod:`spcopyro.config` (``from spcopyro.config import DataPreparation``). Imports nothing from
the package but its plumbing (``spcopyro._util``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal, get_args

from spcopyro._util.messages import one_of
from spcopyro._util.number_checks import is_finite_number, is_positive_number

FeatureScaling = Literal["probability", "floor100"] | float
"""How image histograms become counts: as they are, floor(100 f) (the released code), or s * f."""
WordWeighting = Literal["count", "tfidf"]
"""Word counts as they are, or tf-idf weighted (paper eq. 20)."""
WordWeightingSetting = Literal["count", "tfidf", "auto"]
"""A :data:`WordWeighting`, or ``"auto"``: tf-idf when at least 30% of the utterances are
sentences (more than one token), counts otherwise, resolved once the data are known
(:mod:`spcopyro.data.word_weighting`)."""
WORD_WEIGHTINGS: tuple[str, ...] = get_args(WordWeightingSetting)
"""The values of :data:`WordWeightingSetting`: ``("count", "tfidf", "auto")``."""
RESOLVED_WORD_WEIGHTINGS: tuple[str, ...] = get_args(WordWeighting)
"""The values of :data:`WordWeighting`, those ``"auto"`` resolves to: ``("count", "tfidf")``."""
DEFAULT_SNAP_DISTANCE = 0.25  # metres: the largest snap the public houses need
FootprintKernel = Literal["uniform", "gaussian"]
"""How an observation's weight falls off over its footprint (:mod:`spcopyro.data.footprint`)."""


def words_footprint_radius(footprint_radius: float, word_footprint_radius: float | None) -> float:
    """The utterances' footprint radius in metres: ``word_footprint_radius``, or
    ``footprint_radius`` where that is None (:class:`DataPreparation`'s fields)."""
    return footprint_radius if word_footprint_radius is None else word_footprint_radius


def footprint_on(footprint_radius: float, words_radius: float) -> bool:
    """Whether an observation footprint is on: the images' (and further modalities')
    ``footprint_radius`` or the utterances' resolved ``words_radius`` (metres) other than 0.
    The one test of :attr:`DataPreparation.has_footprint` (the kernel's and field of view's
    reads, their warnings) and, with the reach share, of :func:`footprint_spreads`. Radii are
    not validated here: a negative one goes on to the footprint's own error, as before (not
    off)."""
    return bool(footprint_radius) or bool(words_radius)


def footprint_spreads(footprint_radius: float, words_radius: float, reach_share: float) -> bool:
    """Whether the counts spread observations beyond their own cells: a footprint is on
    (:func:`footprint_on`) or the ``reach_share`` (``DataPreparation.footprint_reach_share``)
    is other than 0, which spreads even at radius 0. The one test of
    :attr:`DataPreparation.spreads` and of :func:`~spcopyro.data.counts.cell_counts` (whose
    arguments are not validated: a bad share goes on to the footprint's own error)."""
    return footprint_on(footprint_radius, words_radius) or bool(reach_share)


@dataclass(frozen=True)
class DataPreparation:
    """How observations become the per-cell counts the model reads
    (:func:`spcopyro.data.cell_counts`).

    Attributes:
        feature_scaling: how image histograms become counts: ``"probability"`` (as they are),
            ``"floor100"`` (floor(100 f), the released code) or a float s (s * f).
        word_weighting: ``"count"``, ``"tfidf"`` (paper eq. 20, for sentences) or ``"auto"``
            (the default): tf-idf when at least 30% of the utterances are sentences (more than
            one token), counts otherwise; a fit resolves it once the data are known and
            records the resolved value (:mod:`spcopyro.data.word_weighting`).
        snap_distance: metres within which an observation off free space is moved to the nearest
            free cell (farther ones are reported and left out).
        footprint_radius: metres; > 0 spreads each observation over the free cells within this
            geodesic distance of its cell, with weights summing to one observation (the
            observation footprint, :mod:`spcopyro.data.footprint`); 0: its own cell only (the
            paper). A switch of the *model* realised here, in the counts, on purpose: the
            footprint's likelihood, the tempered product prod_c p(x_t | C_c)^{w_tc}, equals the
            plain model's on the weighted counts sum_t w_tc x_t up to a constant, so the Pyro
            model, both Gibbs backends, CAVI and every other method read it unchanged.
        word_footprint_radius: metres, or None (the default: ``footprint_radius``'s): the
            utterances' own footprint radius, the images (and further modalities) keeping
            ``footprint_radius``; 0: each utterance counted whole at its own cell (the paper's
            words). In the model each utterance's likelihood is the tempered product
            prod_c p(w_d | C_c)^{w_dc} over its own footprint (weights w_dc within this radius,
            the disc: words have no direction; at 0 the one factor of its cell), each image's
            over ``footprint_radius``'s. Why 0 may matter: a footprint's fractional counts break
            ties between words said equally often at one spot (by the share of each utterance's
            disc inside a concept; docs/real_houses.md, room1ldk5).
        footprint_kernel: ``"uniform"`` or ``"gaussian"`` (sigma = radius / 2) weights.
        footprint_fov: degrees: an image informs only the cells within +-fov/2 of its yaw
            (needs the data's image yaw); None: the whole disc. Read only where
            ``footprint_radius`` > 0: words always use the disc.
        footprint_reach_share: e in [0, 1): each observation's weight split into 1 - e over its
            footprint (as above; its own cell where the radius is 0) and e spread uniformly
            over its geodesic Voronoi cell among the observed cells of its modality, so that
            some of each place's evidence reaches the border half-way to the next observation
            (:mod:`spcopyro.data.footprint`, "Reaching the Voronoi border"); still one
            observation in total, the same tempered product. 0 (the field's default; preset
            ``coarse``'s is 0.2): off, the footprint exactly as without it. A 0 given over a
            preset's share drops the preset's cuts below (:data:`~spcopyro.config.REACH_CUTS`).
        footprint_reach_radius: metres > 0, or None (the default: no limit): the Voronoi cells
            of ``footprint_reach_share`` cut at that geodesic distance from their observed
            cell, so a spot's share stays within it (a sparse house's doorway into the next,
            unobserved room; "Bounding the reach"). Refused where the share is 0.
        footprint_reach_door_width: metres > 0, or None (the field's default: no cut; preset
            ``coarse``'s is 1.0): the Voronoi cells of ``footprint_reach_share`` drawn within
            the room segments at doorways up to that wide
            (:func:`spcopyro.maps.rooms.room_segments` on the grid the counts are on; 1 m is the
            rooms start's and baseline (F)'s), so a room where no observation of a modality lies
            gets none of its Voronoi weight while an open plan's one walled space is spread as
            without it ("Voronoi cells within rooms"). Refused where the share is 0 (a preset's
            door width is dropped instead where a share of 0 is given over the preset's).
        word_scaling: s > 0: each utterance's word counts (or tf-idf weights) times s, the
            words' weight against the images and the MRF (1: the paper). A tempered likelihood,
            as ``feature_scaling`` is for images (``floor100`` counts a histogram as 100 draws).
        cell_size: metres, or None (the map's own cells, the paper): the model's grid. The map is
            coarsened to cells of ``floor(cell_size / resolution + 1/2)`` map cells a side
            (:mod:`spcopyro.maps.coarse`: a model cell is free when at least half of its map
            cells are free and none is occupied), so the Potts border cost per metre and the
            number of unobserved cells voting in the label prior no longer grow with the map's
            resolution (docs/real_houses.md). The fit's result lives on that grid.
    """

    feature_scaling: FeatureScaling = "probability"
    word_weighting: WordWeightingSetting = "auto"
    snap_distance: float = DEFAULT_SNAP_DISTANCE
    footprint_radius: float = 0.0
    word_footprint_radius: float | None = None
    footprint_kernel: FootprintKernel = "uniform"
    footprint_fov: float | None = None
    word_scaling: float = 1.0
    cell_size: float | None = None
    footprint_reach_share: float = 0.0
    footprint_reach_radius: float | None = None
    footprint_reach_door_width: float | None = None

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ValueError:
            return ValueError(f"DataPreparation.{name}={getattr(self, name)!r}: {why}")

        fs = self.feature_scaling
        if not (fs in ("probability", "floor100") or is_positive_number(fs)):
            raise bad("feature_scaling", "must be 'probability', 'floor100' or a positive float")
        if self.word_weighting not in WORD_WEIGHTINGS:
            raise bad("word_weighting", f"must be {one_of(WORD_WEIGHTINGS)}")
        snap = self.snap_distance
        if not (is_finite_number(snap) and snap >= 0):
            raise bad("snap_distance", "must be a finite number of metres >= 0")
        radius = self.footprint_radius
        if not (is_finite_number(radius) and radius >= 0):
            raise bad("footprint_radius", "must be a finite number of metres >= 0 (0: off)")
        words = self.word_footprint_radius
        if words is not None and not (is_finite_number(words) and words >= 0):
            raise bad("word_footprint_radius", "must be None (footprint_radius's) or a finite "
                      "number of metres >= 0 (0: each utterance at its own cell)")  # fmt: skip
        if self.footprint_kernel not in ("uniform", "gaussian"):
            raise bad("footprint_kernel", "must be 'uniform' or 'gaussian'")
        fov = self.footprint_fov
        if fov is not None and not (is_finite_number(fov) and 0 < fov <= 360):
            raise bad("footprint_fov", "must be None or an angle in degrees in (0, 360]")
        share = self.footprint_reach_share
        if not (is_finite_number(share) and 0 <= share < 1):
            raise bad("footprint_reach_share", "must be a number in [0, 1): the share of each "
                      "observation spread over its Voronoi cell (0: off)")  # fmt: skip
        cut = self.footprint_reach_radius
        if cut is not None and not is_positive_number(cut):
            raise bad("footprint_reach_radius", "must be None (no limit) or a finite number of "
                      "metres > 0: the Voronoi cells' cut")  # fmt: skip
        if cut is not None and not share:  # it would change nothing but skip the refinement
            raise bad("footprint_reach_radius", "cuts the Voronoi cells of "
                      "footprint_reach_share, which is 0: give a share > 0 "
                      "(--footprint-reach-share) or no radius")  # fmt: skip
        door = self.footprint_reach_door_width
        if door is not None and not is_positive_number(door):
            raise bad("footprint_reach_door_width", "must be None (no cut) or a finite number "
                      "of metres > 0: the doorways the Voronoi cells are cut at")  # fmt: skip
        if door is not None and not share:  # as the radius: no count changed, refinement lost
            raise bad("footprint_reach_door_width", "cuts the Voronoi cells of "
                      "footprint_reach_share, which is 0: give a share > 0 "
                      "(--footprint-reach-share) or no door width")  # fmt: skip
        ws = self.word_scaling
        if not is_positive_number(ws):
            raise bad("word_scaling", "must be a positive finite number (1: the paper)")
        size = self.cell_size
        if size is not None and not is_positive_number(size):
            raise bad("cell_size", "must be None (the map's cells) or a positive number of metres")

    def replace(self, **changes: object) -> DataPreparation:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    @property
    def words_radius(self) -> float:
        """The utterances' footprint radius in metres: ``word_footprint_radius``, or
        ``footprint_radius`` where that is None."""
        return words_footprint_radius(self.footprint_radius, self.word_footprint_radius)

    @property
    def has_footprint(self) -> bool:
        """Whether any observation is spread over a footprint: ``footprint_radius`` > 0 or the
        utterances' :attr:`words_radius` > 0 (the kernel is read then; the field of view only
        where ``footprint_radius`` > 0: it applies to images)."""
        return footprint_on(self.footprint_radius, self.words_radius)

    @property
    def spreads(self) -> bool:
        """Whether the counts spread any observation beyond its own cell: :attr:`has_footprint`
        or a ``footprint_reach_share`` > 0 (:func:`footprint_spreads`); the observed cells are
        then the cells the spread reaches, not only where observations were placed."""
        return footprint_spreads(self.footprint_radius, self.words_radius,
                                 self.footprint_reach_share)  # fmt: skip

    def reads(self, field: str) -> bool:
        """Whether the counts read the footprint setting ``field``: ``"footprint_kernel"``
        where any footprint is on (:attr:`has_footprint`, the words' own too),
        ``"footprint_fov"`` only where ``footprint_radius`` > 0 (it applies to images: words
        always use the disc). The one rule of the warnings, records and summaries of a setting
        given where it does nothing."""
        if field == "footprint_kernel":
            return self.has_footprint
        if field == "footprint_fov":
            return bool(self.footprint_radius)
        raise ValueError(f"reads: {field!r} is not 'footprint_kernel' or 'footprint_fov'")

    def to_json(self) -> dict[str, object]:
        """The fields as JSON values, as saved (config.json, checkpoints, records):
        ``word_footprint_radius``, ``footprint_reach_share``, ``footprint_reach_radius`` and
        ``footprint_reach_door_width`` only where set (not None, not 0), so a preparation
        without them saves as before they existed and what was saved then loads as it was."""
        values = dataclasses.asdict(self)
        if self.word_footprint_radius is None:
            del values["word_footprint_radius"]
        if not self.footprint_reach_share:
            del values["footprint_reach_share"]
        if self.footprint_reach_radius is None:
            del values["footprint_reach_radius"]
        if self.footprint_reach_door_width is None:
            del values["footprint_reach_door_width"]
        return values
