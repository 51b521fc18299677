"""``spcopyro fit``'s "model", "data" and "inference" lines: what is fitted, as a person reads
it -- the preset, then the values that matter as ``name value``, leaving out what is at its
off or neutral value. They printed the dataclasses' reprs (``GibbsOptions(backend='auto', ...,
hyper=HyperparameterOptions(alpha=False, ...), region_moves=0.2)``); every setting stays in
OUT/config.json, which the inference line points to."""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

from spcopyro._util.messages import plural
from spcopyro.inference.names import objective_draws
from spcopyro.inference.protocol import options_for_start, start_filled
from spcopyro.maps.coarse import coarsening_factor
from spcopyro.results.estimate_names import KEEPS_SPECKS, LOSS_LABELS, estimate_loss
from spcopyro.results.refined import coarse_stage

if TYPE_CHECKING:
    from spcopyro.config import DataPreparation, SpCoConfig
    from spcopyro.maps.grid import OccupancyGrid
    from spcopyro.results.result import SpCoResult

__all__ = [
    "data_line",
    "estimate_line",
    "inference_line",
    "model_line",
    "objective_line",
    "reach_cut_text",
    "stopped_line",
]

LABEL = 17
"""The width of the summary's label column: each line's label (``model``, ``data``,
``inference``) padded with spaces to 17 characters."""


def _number(value: float) -> str:
    """``value`` short: 3, 0.1, 2.5, 1e7 (``:g``'s 1e+07 without its plus and zero)."""
    text = f"{value:g}"
    mantissa, e, exponent = text.partition("e")
    return f"{mantissa}e{int(exponent)}" if e else text


def reach_cut_text(radius: float | None, door_width: float | None = None) -> str:
    """How the reach share's Voronoi cells are cut, as the fit's summary says it (its data line
    and its observed-cells line, :mod:`spcopyro.cli.common`): ``"Voronoi cells"``, with
    ``" within 2 m"`` for a radius and ``" within rooms at 1 m doors"`` for a door width, both
    joined by a comma (numbers as ``:g`` writes them)."""
    cuts = [] if radius is None else [f"within {radius:g} m"]
    if door_width is not None:
        cuts.append(f"within rooms at {door_width:g} m doors")
    return f"Voronoi cells {', '.join(cuts)}" if cuts else "Voronoi cells"


def model_line(config: SpCoConfig, preset: str | None, images_missing: bool = False) -> str:
    """The "model" line: the preset, then L, the prior and alpha, gamma and its neighbourhood,
    beta, chi, each further modality's concentration, and a modality switched off.
    ``images_missing``: the house has no images, so the model in effect uses words only
    (config.json keeps ``use_images`` as asked)."""
    prior = config.prior if config.prior == "dp" else "finite Dirichlet"
    parts = [
        f"{config.num_concepts} concepts ({prior}, alpha {_number(config.alpha)})",
        f"gamma {_number(config.gamma)} ({config.connectivity}-neighbour)",
        f"beta {_number(config.beta)}",
        f"chi {_number(config.chi)}",
        *(f"{name} {_number(value)}" for name, value in config.concentrations),
    ]
    if images_missing and config.use_images:
        parts.append("words only")
    elif not config.use_images:
        parts.append("no images" if config.use_words else "no images, no words")
    elif not config.use_words:
        parts.append("no words")
    line = f"{'model':<{LABEL}}{f'preset {preset}: ' if preset else ''}{', '.join(parts)}"
    if images_missing and config.use_images:
        line += " (no images here: use_images=True, as config.json records it, has none to use)"
    return line


def data_line(
    preparation: DataPreparation, grid: OccupancyGrid | None = None, word_note: str | None = None
) -> str:
    """The "data" line: the model's grid, then how the images and words are counted and spread;
    the word weighting where it is tf-idf or a ``word_note`` explains it, a word scaling other
    than 1, a footprint and a snap distance other than the default only where set.
    ``grid``: the model's grid the fit uses (``model_house``), whose cells are a whole number of
    the map's and so may differ from the cell size asked: the line gives the size used, with the
    one asked beside it where they differ. ``word_note``: why the word weighting is the one it
    is (``auto: 27 of 54 utterances are sentences (50%; tf-idf from 30%)``;
    :func:`spcopyro.cli.fit_settings.word_weighting_note`), None for counts as ever."""
    from spcopyro.config import DEFAULT_SNAP_DISTANCE

    p = preparation
    parts = [_cells(p.cell_size, grid), f"feature scaling {_value(p.feature_scaling)}"]
    if word_note:
        parts.append(f"word weighting {p.word_weighting} ({word_note})")
    elif p.word_weighting == "tfidf":  # counts (an auto unresolved too), unexplained: as ever
        parts.append("word weighting tfidf")
    if p.word_scaling != 1.0:
        parts.append(f"word scaling {_number(p.word_scaling)}")
    if p.has_footprint:
        fov = ""
        if p.footprint_fov is not None and p.reads("footprint_fov"):  # images' only
            fov = f", images {_number(p.footprint_fov)} deg wide"
        if p.words_radius != p.footprint_radius:  # --word-footprint: the words' own
            fov += f", words {_number(p.words_radius)} m" if p.words_radius else ", words at cell"
        parts.append(f"footprint {_number(p.footprint_radius)} m ({p.footprint_kernel}{fov})")
    if p.footprint_reach_share:
        cut = reach_cut_text(p.footprint_reach_radius, p.footprint_reach_door_width)
        parts.append(f"reach share {_number(p.footprint_reach_share)} ({cut})")
    if p.snap_distance != DEFAULT_SNAP_DISTANCE:
        parts.append(f"snap distance {_number(p.snap_distance)} m")
    return f"{'data':<{LABEL}}{', '.join(parts)}"


def _cells(asked: float | None, grid: OccupancyGrid | None) -> str:
    """The model's cells: ``cells 0.25 m`` as asked, or, where the grid's differ from
    ``asked``, the size used with the one asked (``cells 0.3 m (0.25 m asked: a whole number
    of the map's 0.1 m cells)``)."""
    if asked is None:
        return "the map's own cells"
    if grid is None or math.isclose(grid.resolution, asked, rel_tol=1e-9):
        return f"cells {_number(asked)} m"
    own = grid.coarsened_from is None  # the map's own cells (rounded to them, or none free)
    map_cells = f"the map's {_number((grid.coarsened_from or grid).resolution)} m cells"
    used = f"the map's own {_number(grid.resolution)} m cells" if own else (
        f"cells {_number(grid.resolution)} m"
    )  # fmt: skip
    if own and coarsening_factor(grid.resolution, asked) > 1:  # coarser cells left none free
        return f"{used} ({_number(asked)} m asked leaves no free cell of {map_cells})"
    return f"{used} ({_number(asked)} m asked: a whole number of {map_cells})"


def _value(value: object) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float | int):
        return _number(value)
    return str(value)


def _changed(options: object, filled: dict[str, object], start: str) -> list[str]:
    """``name value`` for each field of dataclass ``options`` away from its class default
    (a nested dataclass as ``name (its fields)``; Gibbs's ``hyper`` only where it samples
    something), and each field left to the start with the value it runs (``(random start)``)."""
    parts = []
    for field in dataclasses.fields(options):  # type: ignore[arg-type]
        if not field.repr:
            continue
        value, name = getattr(options, field.name), field.name.replace("_", " ")
        if field.name in filled:
            parts.append(f"{name} {_value(filled[field.name])} ({start})")
            continue
        if dataclasses.is_dataclass(value):
            if getattr(value, "active", True):  # HyperparameterOptions: something sampled
                inner = _changed(value, {}, start)
                label = "sampled hyperparameters" if hasattr(value, "active") else name
                parts += [f"{label} ({', '.join(inner)})"] if inner else []
            continue
        default = field.default
        if default is dataclasses.MISSING and field.default_factory is not dataclasses.MISSING:
            default = field.default_factory()
        if value is True and hasattr(options, "active"):  # a sampled hyperparameter
            parts.append(name)
        elif value != default:
            parts.append(f"{name} {_value(value)}")
    return parts


def inference_line(method: str, options: object, given: bool, budget: str, out: str) -> str:
    """The "inference" line: the method, ``budget`` (``5000 sweeps``, ``4 chains``), then its
    options that differ from the method's defaults as ``name value`` (``merge moves 0.2``), with
    a field left to the start (svi's ``label_smoothing``) given the value this start runs, then
    where every setting is (``out``'s config.json)."""
    parts = [budget] if budget else []
    if dataclasses.is_dataclass(options):
        filled = start_filled(options, options_for_start(options, given_start=given))
        parts += _changed(options, filled, "given start" if given else "random start")
    shown = ", ".join(parts)
    return f"{'inference':<{LABEL}}{method}: {shown} (every setting: {out}/config.json)"


def stopped_line(result: SpCoResult) -> str:
    """A variational fit's "stopped" line: why it stopped (``inference['stopped']``) and the
    final value of its objective, named, in nats ("final ELBO -1422.2 nats"; SVI's "ELBO
    estimate", one draw's). The line said "the objective changed by less than ..." and no value:
    comparing two variational fits meant opening their trace.csv."""
    estimated = objective_draws(result.method, result.inference) > 0
    name = result.trace.objective_name + (" estimate" if estimated else "")
    value = float(result.trace.objective[-1])  # [iterations]: the reported q's, the last
    return f"{'stopped':<{LABEL}}{result.inference['stopped']}; final {name} {value:.1f} nats"


def objective_line(result: SpCoResult) -> str | None:
    """The summary's line of a fit's objective: a variational fit's :func:`stopped_line`; a
    sampler's (Gibbs, vi-gibbs: a log joint trace) highest log joint, in nats, and the sweep
    that reached it (1-based, as trace.csv's ``iteration``; a refined fit's: of its sweeps on
    the map's cells, the trace it keeps): "log joint        highest 118432.1 nats, at sweep 4210
    of 5000". A Gibbs fit printed no objective at its end, a variational one its final ELBO.
    None for a fit of neither (no trace)."""
    if result.inference.get("stopped"):
        return stopped_line(result)
    if result.trace.objective_name != "log joint" or not len(result.trace.objective):
        return None
    if not math.isfinite(result.best_objective):  # [sweeps] none finite
        return None
    where = " on the map's cells" if coarse_stage(result.inference) is not None else ""
    return (f"{'log joint':<{LABEL}}highest {result.best_objective:.1f} nats, at sweep "
            f"{result.best_iteration + 1} of {len(result.trace.objective)}{where} "
            "(every sweep's: trace.csv)")  # fmt: skip


def _signed(change: float) -> str:
    """``change`` signed, to two significant digits, without an exponent: ``+0.00078``,
    ``+0.000076`` (``+7.6e-05`` read as a different kind of number beside ``0.1558``)."""
    if change == 0 or not math.isfinite(change):
        return f"{change:+g}"
    return f"{change:+.{max(0, 1 - math.floor(math.log10(abs(change))))}f}"


def estimate_line(result: SpCoResult, estimate: str, figures: bool) -> str:
    """The summary's "point estimate" line of a result whose map is the point estimate
    ``estimate`` (``vi``, ``binder``, ``vi-specks``, ...; the result's own where it records it):
    its expected loss, the best single sample's, and, where speck cells were joined to other
    concepts (:mod:`spcopyro.results.speck_join`), how many and the loss before, e.g.
    ``point estimate   vi (expected variation of information 0.1558, best single sample 0.201;
    6 speck cells joined to other concepts: +0.00078 from 0.155, vi-specks keeps them);
    agreement.png``."""
    options = result.inference
    estimate = str(options.get("point_estimate", estimate))  # a refit's own
    loss, _ = estimate_loss(estimate)
    named = LOSS_LABELS["vi"] if loss == "vi" else "loss"  # not variational inference
    text = (f"{'point estimate':<{LABEL}}{estimate} (expected {named} "
            f"{options['expected_loss']:.4g}, best single sample "
            f"{options['best_sample_loss']:.4g}")  # fmt: skip
    joined = int(options.get("speck_cells_joined") or 0)  # type: ignore[call-overload]
    if joined:
        before = float(options["loss_with_specks"])  # type: ignore[arg-type]
        change = float(options["expected_loss"]) - before  # type: ignore[arg-type]
        text += (f"; {plural(joined, 'speck cell')} joined to other concepts: {_signed(change)} "
                 f"from {before:.4g}, "
                 f"{loss}{KEEPS_SPECKS} keeps them")  # fmt: skip
    return text + ")" + ("; agreement.png" if figures else "")
