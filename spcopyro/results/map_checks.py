"""Checks of a fitted map against the observations: is the map degenerate? (issue 21, item 5)

A map is *degenerate* when one concept holds most of the free cells while words said at
different places lie inside it: the fit has not separated the places those words name (too
strong a Potts coupling for the data, emissions that the data cannot move, or a chain that
coarsened into one region). It is degenerate too when one concept holds most of the free cells
but few of the words, and the words said at different places lie *outside* it, in concepts that
together hold only a small share of the map: each word names a patch around where it was said,
and one concept is left over the rest of the house (CAVI on room1dk5 under ``original-code``,
gamma 3, 100 iterations: one concept over 94% of the free cells holding 6 of the 57 utterances,
the other 51 in concepts of 12-124 cells, together 5.1% of the map).
:func:`degenerate_map_warning` says so, naming the words;
:func:`house_map_warning` places a house's utterances on the map's cells first, as the fit does.
:func:`spcopyro.fit.house.fit_house` and ``spcopyro fit`` log it (logger ``"spcopyro"``).

The rule (numpy only)::

    share = (cells of the largest concept c) / (free cells)
    warn  if share > DEGENERATE_SHARE
          and, over the utterances placed on c's cells, the mean positions of at least two
              distinct words are at least DEGENERATE_SEPARATION metres apart
    or    share > PATCHES_SHARE, c holds at most PATCHES_HEARD of the placed utterances,
          over the utterances placed on other concepts' cells the mean positions of at least
              two distinct words are at least DEGENERATE_SEPARATION metres apart,
          and those utterances' concepts together hold less than DEGENERATE_PATCHES of the
              free cells

Every token of an utterance counts as a word (the word preparation drops none: see
:mod:`spcopyro.data.text`); a word's count is the number of the utterances it is named among
(c's, or those outside c) that hold it.

A map is *short of concept slots* when a fit under the weak-limit Dirichlet-process prior
(``prior="dp"``: L, ``num_concepts``, is only an upper bound on the concepts) reports at least
:data:`SATURATED_SLOTS` of its L concepts in use and its labels form regions
(:data:`REGION_AGREEMENT`; patches fill every slot whatever L is): the prior can hold no more,
so places may be merged for want of concepts (a synthetic house of 519k free cells used 113 of
120, one of 960k all 120). :func:`concept_slots_warning` says so, with the remedy (a larger L);
not under a finite Dirichlet prior, where L is the known number of concepts.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from typing import TYPE_CHECKING

import numpy as np

from spcopyro._util.context import set_within
from spcopyro._util.messages import setting, shown_count
from spcopyro.config import DEFAULT_PRESET

if TYPE_CHECKING:
    from spcopyro.config import SpCoConfig
    from spcopyro.data import House
    from spcopyro.maps import OccupancyGrid

__all__ = [
    "MIN_COVERAGE",
    "coverage_warning",
    "DEGENERATE_PATCHES",
    "DEGENERATE_SEPARATION",
    "DEGENERATE_SHARE",
    "NAMED_WORDS",
    "PATCHES_HEARD",
    "PATCHES_SHARE",
    "REGION_AGREEMENT",
    "SATURATED_SLOTS",
    "concept_slots_warning",
    "degenerate_map_advice",
    "degenerate_map_warning",
    "house_map_warning",
    "is_degenerate_map_warning",
    "WARNING_START",
]

DEGENERATE_SHARE = 0.6
"""Share of the free cells above which the largest concept may be a degenerate map: a house
with rooms of distinct names rarely has one room over 60% of its floor. Measured under Gibbs
(``fit --sweeps 300 --seed 0``) with the paper's presets on the five public houses: the largest
concept held 1.0-1.1% of the free cells (``original-code``), 3.5-9.5% (``paper-dp``) and
18.6-39.4% (``paper-dirichlet``, L = the rooms' count): no warning, rightly; with
``--concepts 1`` each preset's one concept (100%, words 7.3 m apart on room1dk5) warned once."""
DEGENERATE_SEPARATION = 1.5
"""Metres: two words whose utterances inside the largest concept have mean positions at least
this far apart were said at different places (a room's length; utterances of one spot, rounded
onto a 5 cm grid or snapped 0.25 m, stay well within it)."""
PATCHES_SHARE = 0.5
"""Share of the free cells above which the largest concept, holding few utterances, may leave the
words small patches (:data:`DEGENERATE_PATCHES`). Measured: the largest concept of good maps
holds 19% (the README's default fit of the embedded house), 35% and 48% (default ``coarse`` fits
of room1ldk4 and room2ldk4 at 300 sweeps); of CAVI's maps under ``original-code`` at gamma 1-3 on
the five public houses, 53-94% (the two at 53% with their words' concepts 43-45% of the map)."""
PATCHES_HEARD = 0.25
"""Share of the placed utterances at most which that largest concept holds: a room over half of
a house is where many words are said. Measured: CAVI's degenerate maps' held 0-11% where the
words lay outside (the good maps' largest: 14-45%, so this alone does not tell them apart)."""
DEGENERATE_PATCHES = 0.2
"""Share of the free cells below which the concepts of the words said outside that largest
concept are small patches, not the rooms those words name. Measured: 2-18% on CAVI's maps above
(largest concept over 57%); 52-81% on the good maps (the named rooms beside the largest)."""
NAMED_WORDS = 8
"""The warning names at most this many words, most heard first (all of them where one is over:
naming it takes no more room than "and 1 more")."""
WARNING_START = "one concept ("
"""How :func:`degenerate_map_warning`'s message begins, either form (a report that counts the
collapsed maps among a study's warnings reads it: :func:`is_degenerate_map_warning`)."""


_ADVICE: ContextVar[Callable[[bool], str] | None] = ContextVar(
    "degenerate_map_advice", default=None
)
"""The advice of :func:`degenerate_map_advice` in force in this context (thread), if any."""


@contextmanager
def degenerate_map_advice(advice: Callable[[bool], str]) -> Iterator[None]:
    """Within (this thread's context): a degenerate-map warning given no ``advice`` of its own
    -- ``fit_house``'s, which names ``fit``'s options -- closes with ``advice(sampled)``
    instead (``sampled``: as :func:`degenerate_map_warning`'s). A study cell's fit gives its
    advice in the study file's own terms this way (:func:`spcopyro.study.evaluate.advice`)."""
    with set_within(_ADVICE, advice):
        yield


def is_degenerate_map_warning(message: str) -> bool:
    """Whether a logged ``message`` is :func:`degenerate_map_warning`'s."""
    return message.lstrip().startswith(WARNING_START)


def degenerate_map_warning(
    labels: np.ndarray,
    utterance_cells: np.ndarray,
    utterance_xy: np.ndarray,
    utterances: Sequence[Sequence[str]],
    sampled: bool = True,
    advice: str | None = None,
    default_preset_skipped: bool | None = None,
) -> str | None:
    """A warning when the map is degenerate (see the module docstring), else None.

    Args:
        labels: ``[N]`` int, the concept of every free cell (free-index order).
        utterance_cells: ``[U]`` int, the free cell each utterance was placed on (-1: unplaced;
            :func:`~spcopyro.data.place_observations`).
        utterance_xy: ``[U, 2]`` world positions (metres) of the utterances.
        utterances: ``[U]`` each utterance's tokens.
        sampled: the fit ran the Gibbs sampler (``gibbs``, ``vi-gibbs``), whose split-merge
            moves (``--merge-moves``) it names; else it names ``--method gibbs`` with them
            (``fit`` refuses ``--merge-moves`` with a variational method).
        advice: the message's closing parenthesis in place of ``fit``'s options (a comparison
            cell's, whose command takes none of them); None: that of the
            :func:`degenerate_map_advice` in force, else ``fit``'s.
        default_preset_skipped: in ``fit``'s advice, for settings from the default preset
            (:data:`~spcopyro.config.DEFAULT_PRESET`): True when the fit was not given the
            inference that preset recommends (``fit_house`` without ``preset_fit_kwargs``'s
            options: the advice names them), False when it was (the advice names no preset);
            None (settings of another preset, or not known): it names the default preset.

    The message names the concept, its share of the free cells and the words heard inside it
    (most heard first, at most :data:`NAMED_WORDS`, with their counts); or, where the words lie
    outside it in small concepts, those words with their counts and their concepts' sizes, and
    the words heard inside it.
    """
    labels = np.asarray(labels).reshape(-1)  # [N]
    cells = np.asarray(utterance_cells, dtype=np.int64).reshape(-1)  # [U]
    xy = np.asarray(utterance_xy, dtype=np.float64).reshape(-1, 2)  # [U, 2]
    if not (len(cells) == len(xy) == len(utterances)):
        raise ValueError(
            f"utterance_cells ({len(cells)}), utterance_xy ({len(xy)}) and utterances "
            f"({len(utterances)}) must describe the same utterances"
        )
    if labels.size == 0 or len(cells) == 0:
        return None
    if (cells >= labels.size).any():
        raise ValueError(f"utterance_cells must be free indices below {labels.size} (or -1)")
    concepts, sizes = np.unique(labels, return_counts=True)
    largest = int(np.argmax(sizes))
    concept, share = concepts[largest], sizes[largest] / labels.size
    if share <= min(DEGENERATE_SHARE, PATCHES_SHARE):
        return None
    placed = cells >= 0  # [U]; unplaced utterances lie in no concept
    said = labels[np.maximum(cells, 0)]  # [U] the concept of each (read where placed)
    inside = np.flatnonzero(placed & (said == concept))  # [U_c]
    heard = _words_heard(inside, utterances)
    given = _ADVICE.get()
    if advice is None and given is not None:  # e.g. a study cell's, in its file's terms
        advice = given(sampled)
    if advice is None:  # to a library caller (fit_house) as to spcopyro fit: both names
        moves = (setting("GibbsOptions(merge_moves=0.2)", "--merge-moves 0.2") if sampled
                 else setting("method='gibbs' with GibbsOptions(merge_moves=0.2)",
                              "--method gibbs --merge-moves 0.2"))  # fmt: skip
        advice = f"(try a lower {setting('gamma', '--gamma')}, {moves} so that regions can split"
        advice += _preset_advice(default_preset_skipped) + ")"
    apart = _apart(heard, xy)
    if share > DEGENERATE_SHARE and apart >= DEGENERATE_SEPARATION:
        return (
            f"{WARNING_START}{concept}) holds {share:.0%} of the free cells while words said at "
            f"different places (up to {apart:.1f} m apart) lie inside it: {_named(heard)}; "
            f"the map does not separate the places these words name {advice}"
        )
    outside = np.flatnonzero(placed & (said != concept))  # [U_o]
    elsewhere = _words_heard(outside, utterances)
    apart = _apart(elsewhere, xy)
    size_of = dict(zip(concepts.tolist(), sizes.tolist(), strict=True))
    patches = sorted(set(said[outside].tolist()))  # the concepts the words outside lie in
    patch_share = sum(size_of[k] for k in patches) / labels.size
    if (
        share <= PATCHES_SHARE
        or len(inside) > PATCHES_HEARD * placed.sum()
        or apart < DEGENERATE_SEPARATION
        or patch_share >= DEGENERATE_PATCHES
    ):
        return None

    def patch_sizes(us: list[int]) -> str:
        """``us``' concepts' sizes, e.g. "in 2 concepts of 100-106 cells"."""
        held = sorted({size_of[int(said[u])] for u in us})
        many = len({int(said[u]) for u in us})
        span = f"{held[0]}" if held[0] == held[-1] else f"{held[0]}-{held[-1]}"
        return f"in {many} concept{'s' if many > 1 else ''} of {span} cells"

    named = _named(elsewhere, patch_sizes)
    held = f": {_named(heard)}" if heard else ""
    return (
        f"{WARNING_START}{concept}) holds {share:.0%} of the free cells and {len(inside)} of the "
        f"{placed.sum()} placed utterances{held}, while words said at different places (up to "
        f"{apart:.1f} m apart) lie outside it in small concepts, together {patch_share:.1%} of "
        f"the free cells: {named}; the map gives these words patches around where they were "
        f"said, not the places they name {advice}"
    )


def _preset_advice(skipped: bool | None) -> str:
    """The clause of ``fit``'s advice that names a preset (see :func:`degenerate_map_warning`'s
    ``default_preset_skipped``)."""
    name = f"preset {DEFAULT_PRESET!r}"
    if skipped is None:
        default = setting(name, f"--preset {DEFAULT_PRESET}")
        return f", or the default {default} if the fit used another"
    if not skipped:  # the default preset's settings, run as spcopyro fit runs them
        return ""
    kwargs = f"preset_fit_kwargs({DEFAULT_PRESET!r})"  # only fit_house can leave them out
    return (f", or the inference spcopyro fit runs for {name}: the settings came from {name} "
            f"but fit_house was not given {kwargs}'s options")  # fmt: skip


def _words_heard(us: np.ndarray, utterances: Sequence[Sequence[str]]) -> dict[str, list[int]]:
    """Each word of the utterances ``us`` ``[U_c]`` -> the utterances that hold it, first heard
    first (a word counted once per utterance)."""
    heard: dict[str, list[int]] = {}
    for u in us:
        for word in dict.fromkeys(utterances[u]):
            heard.setdefault(word, []).append(int(u))
    return heard


def _apart(heard: dict[str, list[int]], xy: np.ndarray) -> float:
    """The largest distance (metres) between two words' mean positions (``xy`` ``[U, 2]``);
    0 for fewer than two words."""
    if len(heard) < 2:
        return 0.0
    means = np.stack([xy[us].mean(axis=0) for us in heard.values()])  # [W, 2]
    return float(np.linalg.norm(means[:, None, :] - means[None, :, :], axis=-1).max())


def _named(heard: dict[str, list[int]], detail: Callable[[list[int]], str] | None = None) -> str:
    """The words, most heard first (stable), at most :data:`NAMED_WORDS` (all of them where one
    is over: :func:`~spcopyro._util.messages.shown_count`): "kitchen (3), ..."
    (``detail(us)``: "kitchen (3 in ...)")."""
    ranked = sorted(heard.items(), key=lambda item: -len(item[1]))
    shown = shown_count(len(ranked), NAMED_WORDS)
    named = ", ".join(
        f"{word} ({len(us)}{'' if detail is None else ' ' + detail(us)})"
        for word, us in ranked[:shown]
    )
    more = len(ranked) - shown
    return named + (f", and {more} more" if more > 0 else "")


def house_map_warning(
    labels: np.ndarray,
    house: House,
    snap_distance: float,
    sampled: bool = True,
    advice: str | None = None,
    default_preset_skipped: bool | None = None,
) -> str | None:
    """:func:`degenerate_map_warning` of ``labels`` ``[N]`` on ``house``'s map, its utterances
    placed on free cells as the fit places them (:func:`~spcopyro.data.place_observations`
    with the fit's ``snap_distance``, metres); ``sampled``, ``advice``,
    ``default_preset_skipped``: as there."""
    from spcopyro.data import place_observations

    observations = house.observations
    if len(observations.utterances) == 0:
        return None
    cells, _, _ = place_observations(house.grid, observations.word_xy, snap_distance)
    return degenerate_map_warning(
        labels, cells, observations.word_xy, observations.utterances, sampled, advice,
        default_preset_skipped,
    )  # fmt: skip


MIN_COVERAGE = 0.55
"""Share of the free space's extent (per axis) below which the observations' extent makes a
wrong map resolution likely: a tour of the house covers 0.66-0.96 of it on every public and
synthetic house; a map whose resolution is twice too large shrinks the tour to about half."""


def coverage_warning(house: House) -> str | None:
    """A warning when the observations span less than :data:`MIN_COVERAGE` of the free space's
    extent along both axes (issue 22 item 4: a map whose yaml resolution was off by 2x fitted
    without a word): the map's resolution or origin may be wrong, or the robot saw only part of
    the map. None otherwise."""
    grid, obs = house.grid, house.observations
    positions = np.concatenate([obs.image_xy, obs.word_xy])  # [T + U, 2]
    if grid.num_free < 2 or positions.shape[0] < 2:
        return None
    free_xy = grid.cell_to_world(grid.free_cells)  # [N, 2]
    span = np.ptp(free_xy, axis=0)  # [2]
    if not (span > 0).all():
        return None
    covered = np.ptp(positions, axis=0) / span  # [2]
    if (covered >= MIN_COVERAGE).any():
        return None
    return (
        f"the observations span only {covered[0]:.0%} x {covered[1]:.0%} of the free space of "
        f"map {grid.source or ''} (x x y): if the robot toured the whole map, its resolution "
        f"({grid.resolution:g} m) or origin may be wrong"
    )


SATURATED_SLOTS = 0.9
"""Share of a weak-limit DP's L concepts at and above which a map's concepts in use say that L,
the prior's upper bound, may be merging places (:func:`concept_slots_warning`). Measured under
the default ``coarse`` fit (L = 120): the embedded house and the five public houses report 5-8
concepts (4-7%; docs/real_houses.md, 5000 sweeps), a synthetic house of 127k free cells 23-28
(19-23%; its truth holds 26 connected regions of one category); synthetic houses of 519k-3.9M
free cells (``--sweeps 200``, 2026-12-06; 106 such regions at 519k, 195 at 960k) used 113-120
on the coarse stage (94-100%: saturated; the largest's refinement reported 93, its point
estimate joining specks, before the speck area bound). 90% (108 of 120) lies between: four
times the 127k-cell house's share, below every saturated one. The 960k-cell house used 218
of L = 240 (``refine="never"``), warned again: its rooms and specks fill 91% of that bound."""
REGION_AGREEMENT = 0.85
"""Share of the 4-neighbour pairs of free cells holding the same concept below which a map's
labels are patches, not regions, and a full set of slots says nothing of L
(:func:`concept_slots_warning` is silent): patches fill every slot whatever L is. Measured
(every slot or nearly in use): 0.01-0.22 three sweeps from random labels (``original-code``,
L = 120, gamma 0.5 and 3, a 1299-cell house), 0.16-0.62 two sweeps at L = 10, 0.08-0.42
below the Potts critical coupling (gamma 2.1-2.45, 300-1000 sweeps, the embedded house),
0.74-0.77 with the sampler frozen (``paper-dp`` at gamma 10-12); regions: 0.93-1.00 on the
embedded house at L = 4 (5-300 sweeps), 0.979-0.991 on the saturated coarse stages above
(0.25 m cells, ``refine="never"``), 0.994-0.998 on their refinements' 0.05 m cells."""


def concept_slots_warning(
    labels: np.ndarray,
    grid: OccupancyGrid,
    config: SpCoConfig,
    coarse: tuple[int, float] | None = None,
    disordered: bool = False,
    frozen: bool = False,
) -> str | None:
    """A warning when a fit under the weak-limit DP prior is short of concept slots (the module
    docstring), else None (always under ``prior="dirichlet"``).

    Args:
        labels: ``[N]`` int, the reported concept of every free cell of ``grid``
            (:meth:`~spcopyro.results.result.SpCoResult.labels_of`).
        grid: the map the labels are on (its 4-neighbour pairs,
            :meth:`~spcopyro.maps.grid.OccupancyGrid.neighbour_pairs`).
        config: the fit's model settings (``num_concepts`` L, ``prior``, ``gamma``).
        coarse: a refined fit's coarse stage: (its concepts in use, its cell size in metres);
            it warns when either map uses at least :data:`SATURATED_SLOTS` of L (a refinement
            starts from the coarse map, merged places and all, and its point estimate may join
            specks: 120 of 120 on a coarse stage were reported as 93).
        disordered: gamma is below the Potts critical coupling (the fit warned so:
            :func:`~spcopyro.fit.setting_warnings.gamma_warning`).
        frozen: the fit sampled at gamma where the Gibbs sampler freezes (the fit warned so:
            :func:`~spcopyro.fit.setting_warnings.freezes`).

    The rule::

        used  = the concepts in use (of the reported map, or of the coarse stage if more)
        agree = E(C) / P: share of the P 4-neighbour pairs of free cells with the same concept
                (the Potts statistic E(C) of spcopyro.model.potts_agreements, over P pairs)
        warn  if prior == "dp" and used >= ceil(SATURATED_SLOTS * L)
              and agree >= REGION_AGREEMENT

    Labels in patches (``agree`` below :data:`REGION_AGREEMENT`) fill every slot whatever L is:
    a chain a few sweeps from its random start, disorder below the Potts critical coupling or
    a frozen sampler, the last two said by the fit's own warnings
    (:func:`spcopyro.fit.setting_warnings.config_warnings`). The message names ``used`` of L
    and the remedy, an upper bound of 2 L (``num_concepts``, ``fit``'s ``--concepts``), and
    that a refit filling about as large a share of 2 L again holds fragments, not places (more
    sweeps, not slots). Where regions formed while ``disordered`` or ``frozen``, the message
    adds that the labels may be those patches and names gamma first, agreeing with that
    warning.
    """
    if config.prior != "dp":  # a finite Dirichlet: L is the known number of concepts
        return None
    labels = np.asarray(labels)  # [N]
    num = int(config.num_concepts)
    bound = math.ceil(round(SATURATED_SLOTS * num, 9))  # 108 of 120 (round: 0.9 * L's bits)
    used = int(np.unique(labels).size)
    if max(used, 0 if coarse is None else int(coarse[0])) < bound:
        return None
    if _like_neighbours(labels, grid) < REGION_AGREEMENT:  # patches: fill every slot, any L
        return None
    stage = "" if coarse is None else f" ({coarse[0]} on its coarse stage's {coarse[1]:g} m cells)"
    more = 2 * num
    larger = setting(f"num_concepts={more}", f"--concepts {more}")
    message = (
        f"the map uses {used} of its L = {num} concept slots{stage}: the weak-limit "
        f"Dirichlet-process prior holds at most L concepts, so places may be merged for want "
        f"of slots; refit with a larger upper bound, {larger} (a sweep's time and memory grow "
        f"with L); if that refit again fills about 90% of its {more} slots, the extra concepts "
        f"are fragments rather than places (a house of 960k free cells used 218 of 240): run "
        f"more {setting('sweeps', '--sweeps')} instead"
    )
    gamma = setting("gamma", "--gamma")
    if disordered:
        higher = math.log1p(math.sqrt(more))
        message += (
            f"; but with gamma = {config.gamma:g} under the critical coupling "
            f"{config.critical_gamma:.3f} (see its warning) the labels may be disordered "
            f"patches that fill every slot whatever L is (L = {more} raises that coupling to "
            f"{higher:.3f}): raise {gamma} first"
        )
    elif frozen:
        message += (
            f"; but with gamma = {config.gamma:g}, where the Gibbs sampler freezes (see its "
            f"warning), the labels may be the random start's patches, which fill every slot "
            f"whatever L is: lower {gamma} first"
        )
    return message


def _like_neighbours(labels: np.ndarray, grid: OccupancyGrid) -> float:
    """E(C) / P: the share of the P 4-neighbour pairs of ``grid``'s free cells whose concepts
    (``labels`` ``[N]``) are the same; 1 where there is no pair."""
    pairs = grid.neighbour_pairs(4)  # [P, 2]
    if not len(pairs):
        return 1.0
    return float(np.mean(labels[pairs[:, 0]] == labels[pairs[:, 1]]))
