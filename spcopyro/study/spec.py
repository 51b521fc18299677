"""A study, declared: what to fit to what, how long, with which seeds (issue 26 item 1).

A study is a grid: variants x data sources x inference methods x seeds (plus baseline rows x
data x seeds). It is written as a TOML file (:func:`load_study`) or built in Python
(:func:`study_from_dict` with the same keys, or :class:`Study` from its parts)::

    [study]
    name = "ablation-small"
    seeds = 3                      # 0, 1, 2; or a list [0, 4, 7]
    sweeps = 200                   # or per method or variant: { gibbs = 200, cavi = 50 }
    methods = ["gibbs", "cavi"]    # optional; default: each variant's own method (gibbs)
    baselines = ["F-geometry"]     # optional rows of spcopyro.experiments.methods

    [variants.paper-dp]            # a variant: named overrides (see
    preset = "paper-dp"            # spcopyro.experiments.ablation_variants: SpCoConfig,
                                   # DataPreparation, method options, fit_house keywords)
    [variants.orig-g3]
    preset = "original-code"
    gamma = 3.0

    [data.small]                   # synthetic: HouseSpec (factory default | public_like |
    synthetic = "scaled"           # open_plan | scaled) and any HouseSpec field
    height = 30
    width = 40
    num_rooms = 2

    [data.room1dk5]                # a public house under the dataset root ($SPCOPYRO_DATA)
    public = "room1dk5"            # held out: trial (seed mod trials) unless heldout = false

    [data.tour]                    # `simulate --map`: a tour on a map_server map
    map = "room1dk5"               # a public house's map, or a path to MAP.yaml
    door_width = "auto"            # and any MapTour field

Every key is checked when the study is read: a bad one raises :class:`StudyError` naming the
file, the key and the value.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from spcopyro._util.number_checks import is_number
from spcopyro.experiments.ablation_variants import (
    Variant,
    VariantError,
    fit_combination_problem,
    make_variant,
)
from spcopyro.experiments.methods import REGISTRY as BASELINE_REGISTRY
from spcopyro.fit.registry import INFERENCE_METHODS
from spcopyro.results.semantic_map import did_you_mean
from spcopyro.robot.map_simulation import MapTour
from spcopyro.study.lines import key_line, named_key, where_path
from spcopyro.synthetic import HouseSpec

__all__ = [
    "MAPS_PREFIX", "DataSource", "Study", "StudyError", "check_once", "given_twice", "load_study",
    "maps_file_name", "study_from_dict",
]  # fmt: skip

SYNTHETIC_FACTORIES = {
    "default": HouseSpec,
    "public_like": HouseSpec.public_like,
    "open_plan": HouseSpec.open_plan,
    "scaled": HouseSpec.scaled,
}
"""``synthetic = NAME`` of a data source: how its :class:`HouseSpec` is made (``scaled`` needs
``height`` and ``width``)."""

BASELINES = tuple(key for key, row in BASELINE_REGISTRY.items() if not row.spcomapping)
"""Rows a study may add beside its variants (``baselines = [...]``)."""

MAPS_PREFIX = "maps_"
"""A source's figure is ``OUT/maps_<data>.png`` (:mod:`spcopyro.study.maps`)."""


def maps_file_name(data: str) -> str:
    """The report's figure of data source ``data``: ``maps_NAME.png``, every character of NAME
    but letters, digits, ``.``, ``-`` and ``_`` written ``_``. Here, beside the check that no two
    sources share one (:func:`study_from_dict`), as maps imports cells, which imports spec."""
    return MAPS_PREFIX + re.sub(r"[^\w.-]", "_", data) + ".png"


_STUDY_KEYS = {"name", "seeds", "sweeps", "methods", "baselines", "spcoa_iterations",
               "observations_off", "scoring", "description", "ari_every"}  # fmt: skip
SCORINGS = ("study", "comparison")
"""How a study's cells are fitted and scored: ``study`` (:mod:`spcopyro.study.evaluate`) or
``comparison``, as ``compare-inference`` does (:mod:`spcopyro.study.comparison_cell`)."""
_KINDS = ("synthetic", "public", "map")


class StudyError(ValueError):
    """A study that cannot be read: the message names the file, the key and the value (and,
    read from a file, the key's line: ``study.toml:12: [data.small] num_roms = 2: ...``).
    ``where``: the table and key, e.g. ``[data.small] num_roms``."""

    def __init__(self, message: str, where: str | None = None) -> None:
        super().__init__(message)
        self.where = where


@dataclass(frozen=True)
class DataSource:
    """One data source of a study: a synthetic house, a public house or a tour on a map.

    ``options`` are the HouseSpec fields (synthetic) or MapTour fields (map) as (name, value)
    pairs. ``house_seed``: draw the house (or tour) with this seed in every cell; None: with
    the cell's seed. ``heldout``: fit on all trials but one and score the held-out trial's
    words (trial = seed mod the number of trials). ``seeds``: the seeds of this source's cells
    when they differ from the study's (the ablation runs 10 synthetic, 3 public).
    """

    name: str
    kind: str  # "synthetic" | "public" | "map"
    target: str  # synthetic: a key of SYNTHETIC_FACTORIES; public: house folder; map: MAP.yaml
    options: tuple[tuple[str, Any], ...] = ()
    house_seed: int | None = None
    heldout: bool = False
    seeds: tuple[int, ...] | None = None
    """This source's seeds (``seeds = N`` or a list in its table); None: the study's."""

    def house_spec(self) -> HouseSpec:
        """A synthetic source's :class:`HouseSpec`."""
        return SYNTHETIC_FACTORIES[self.target](**dict(self.options))

    def map_tour(self) -> MapTour:
        """A map source's :class:`MapTour`."""
        values = dict(self.options)
        if "categories" in values:
            values["categories"] = tuple(values["categories"])
        return MapTour(**values)

    def to_json(self) -> dict[str, object]:
        """The source as JSON values."""
        return {
            "name": self.name, "kind": self.kind, "target": self.target,
            "options": dict(self.options), "house_seed": self.house_seed,
            "heldout": self.heldout, "seeds": None if self.seeds is None else list(self.seeds),
        }  # fmt: skip


@dataclass(frozen=True)
class Study:
    """A declared study (module docstring). ``sweeps`` maps a variant's name, a method or
    ``"*"`` to iterations (:meth:`sweeps_for`); ``methods`` empty: each variant with its own
    method."""

    name: str
    variants: tuple[Variant, ...]
    data: tuple[DataSource, ...]
    seeds: tuple[int, ...] = (0,)
    sweeps: tuple[tuple[str, int], ...] = (("*", 1000),)
    methods: tuple[str, ...] = ()
    baselines: tuple[str, ...] = ()
    spcoa_iterations: int = 100
    observations_off: bool = False
    """Also fit every variant cell with ``use_images = use_words = False`` (same seed) and score
    that map: ``ari_off``, ``ari_on_off``, ``concepts_1pct_off``, ``seconds_off``."""
    scoring: str = "study"
    """:data:`SCORINGS`."""
    ari_every: int = 0
    """Keep a variant's label map every this many iterations and store its ARI against the
    truth in the trace (``ari``, ``ari_iterations``: paper Fig. 5); 0: not."""
    description: str = ""
    source: str = field(default="<python>", compare=False)
    """Where the study was read from (named in errors and in study.json)."""

    def sweeps_for(self, method: str, variant: str | None = None) -> int:
        """The iterations of ``variant`` fitted with ``method``: the variant's own entry, else
        the method's, else ``"*"``."""
        table = dict(self.sweeps)
        if variant is not None and variant in table:
            return int(table[variant])
        return int(table.get(method, table.get("*", 1000)))

    def sweeps_defaulted(self) -> list[str]:
        """The methods some variant runs at the built-in 1000 iterations because ``sweeps``
        is a table naming neither them, the variant nor ``"*"``."""
        table = dict(self.sweeps)
        if "*" in table:
            return []
        methods = {
            method
            for variant in self.variants
            if variant.name not in table
            for method in (self.methods or (variant.method,))
            if method not in table
        }
        return sorted(methods)

    def to_json(self) -> dict[str, object]:
        """The study as JSON values (written beside its results)."""
        return {
            "name": self.name, "description": self.description, "source": self.source,
            "seeds": list(self.seeds), "sweeps": dict(self.sweeps), "methods": list(self.methods),
            "baselines": list(self.baselines), "spcoa_iterations": self.spcoa_iterations,
            "observations_off": self.observations_off, "scoring": self.scoring,
            "ari_every": self.ari_every, "variants": [v.to_json() for v in self.variants],
            "data": [d.to_json() for d in self.data],
        }  # fmt: skip


def load_study(path: str | os.PathLike[str]) -> Study:
    """The study in the TOML file ``path`` (:class:`StudyError` for bad content)."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        try:
            import tomli as tomllib  # type: ignore[no-redef]
        except ModuleNotFoundError:
            raise StudyError(f"{path}: reading TOML on Python 3.10 needs tomli") from None
    source = str(path)
    try:
        with open(path, "rb") as file:
            content = file.read()
        text = content.decode("utf-8-sig")  # a BOM (Windows editors) was "Invalid statement"
        values = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise StudyError(f"{source}: not valid TOML: {error}") from None
    except UnicodeDecodeError as error:  # it said only "'utf-8' codec can't decode byte ..."
        raise StudyError(f"{source}: not UTF-8 text, as TOML is: {error}") from None
    try:
        return study_from_dict(values, source=source)
    except StudyError as error:  # the key's line, for the editor: study.toml:12: ...
        line = key_line(text, where_path(error.where)) if error.where else None
        message = str(error)
        if line is None or not message.startswith(f"{source}: "):
            raise
        raise StudyError(f"{source}:{line}: {message[len(source) + 2 :]}", error.where) from None


def _fail(source: str, where: str, value: object, why: str) -> StudyError:
    return StudyError(f"{source}: {where} = {value!r}: {why}", where)


def _quoted_number(value: object, passes: Callable[[object], bool]) -> str:
    """A hint for a number written in quotes (``sweeps = "1_000"``: TOML reads text), else "".
    Only where the number unquoted would pass ``passes``, the field's own check: "2.5" for a
    count, "0" for one >= 1 or "2" for a share would still fail without the quotes. Not for an
    infinity ("inf"), which no field means."""
    if not isinstance(value, str):
        return ""
    try:
        number: int | float = int(value)
    except ValueError:
        try:
            number = float(value)
        except ValueError:
            return ""
    if not math.isfinite(number) or not passes(number):
        return ""
    return f" (a number in quotes is text: write {value.strip()} without the quotes)"


def _is_int_at_least(value: object, low: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= low


def _seeds(source: str, value: object, where: str = "[study] seeds") -> tuple[int, ...]:
    if isinstance(value, int) and not isinstance(value, bool):
        if value < 1:
            raise _fail(source, where, value, "a count must be >= 1")
        return tuple(range(value))
    if isinstance(value, list | tuple) and value:
        if all(_is_int_at_least(s, 0) for s in value):
            if len(set(value)) != len(value):
                raise _fail(source, where, value, "a seed is given twice")
            return tuple(int(s) for s in value)
    why = "expected a count >= 1 or a list of seeds >= 0"
    raise _fail(source, where, value, why + _quoted_number(value, lambda n: _is_int_at_least(n, 1)))


def _positive_int(source: str, where: str, value: object, minimum: int = 1) -> int:
    if not _is_int_at_least(value, minimum):
        hint = _quoted_number(value, lambda n: _is_int_at_least(n, minimum))
        raise _fail(source, where, value, f"expected an integer >= {minimum}{hint}")
    return int(value)


def _bool(source: str, where: str, value: object) -> bool:
    if not isinstance(value, bool):
        raise _fail(source, where, value, "expected true or false")
    return value


def _sweeps(
    source: str, value: object, variants: tuple[str, ...] = ()
) -> tuple[tuple[str, int], ...]:
    if isinstance(value, Mapping):
        out = []
        for method, count in value.items():
            if method != "*" and method not in INFERENCE_METHODS and method not in variants:
                known = sorted(INFERENCE_METHODS)
                raise _fail(source, f"[study] sweeps.{method}", count,
                            f"unknown method or variant; choose from the methods {known}, the "
                            f"variants {list(variants)} or '*'")  # fmt: skip
            out.append((str(method), _positive_int(source, f"[study] sweeps.{method}", count)))
        return tuple(out)
    return (("*", _positive_int(source, "[study] sweeps", value)),)


def _check_sweeps_used(
    source: str, sweeps: tuple[tuple[str, int], ...], variants: tuple[Variant, ...],
    methods: tuple[str, ...],
) -> None:  # fmt: skip
    """StudyError for an entry of a ``sweeps`` table that no cell takes (a method no variant
    runs, or one every variant running it has its own entry for): it changed nothing."""
    table = dict(sweeps)
    used = {
        variant.name if variant.name in table else method if method in table else "*"
        for variant in variants
        for method in methods or (variant.method,)
    }
    for key, count in sweeps:
        if key != "*" and key not in used:
            runs = sorted({m for v in variants for m in methods or (v.method,)})
            raise _fail(source, f"[study] sweeps.{key}", count,
                        f"no cell takes it (the variants run {runs}; a variant's own entry comes "
                        "before its method's): remove it")  # fmt: skip


def given_twice(values: Sequence[Hashable]) -> Hashable | None:
    """The first value of ``values`` given a second time, or None."""
    seen: set[Hashable] = set()
    for value in values:
        if value in seen:
            return value
        seen.add(value)
    return None


def check_once(option: str, values: Sequence[Hashable] | None) -> None:
    """ValueError naming ``option`` and the value when ``values`` holds one twice (a house,
    method, baseline or variant given twice would run and count its cells twice)."""
    twice = given_twice(values or ())
    if twice is not None:
        raise ValueError(f"{option}: {twice} is given twice")


def _names(source: str, where: str, value: object, known: tuple[str, ...]) -> tuple[str, ...]:
    if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
        raise _fail(source, where, value, "expected a list of names")
    unknown = [v for v in value if v not in known]
    if unknown:
        raise _fail(source, where, value, f"unknown {unknown}; choose from {list(known)}")
    twice = given_twice(value)
    if twice is not None:
        raise _fail(source, where, value, f"{twice!r} is given twice")
    return tuple(value)


def _variants(source: str, table: object, methods: tuple[str, ...]) -> tuple[Variant, ...]:
    if not isinstance(table, Mapping) or not table:
        raise _fail(source, "[variants]", table, "expected at least one [variants.NAME] table")
    variants = []
    for name, overrides in table.items():
        if not isinstance(overrides, Mapping):
            raise _fail(source, f"variants.{name}", overrides, "expected a table of overrides")
        if methods and "method" in overrides:
            raise _fail(source, f"[variants.{name}] method", overrides["method"],
                        "[study] methods is given: it sets every variant's method")  # fmt: skip
        try:  # made for the study's first method: its options were refused as gibbs's
            first = {"method": methods[0]} if methods else {}
            variant = make_variant(name, {**_flatten(overrides), **first})
            for method in methods:  # the variant's options must exist for every method
                try:
                    dataclasses.replace(variant, method=method).method_options()
                except VariantError as error:
                    raise VariantError(f"{error} (for [study] methods' {method!r})") from None
                problem = fit_combination_problem(dict(variant.fit), method)
                if problem:
                    raise VariantError(f"variant {name!r}: {problem}")
        except VariantError as error:
            key = named_key(str(error), list(_flatten(overrides)))
            where = f"[variants.{name}]" + (f" {key}" if key else "")
            raise StudyError(f"{source}: [variants.{name}]: {error}", where) from None
        variants.append(variant)
    return tuple(variants)


def _flatten(overrides: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{hyper = {alpha = 1}}`` -> ``{"hyper.alpha": 1}`` (nested method options)."""
    flat: dict[str, Any] = {}
    for key, value in overrides.items():
        if isinstance(value, Mapping):
            flat.update(_flatten(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def _data_source(source: str, name: str, table: object) -> DataSource:
    where = f"[data.{name}]"
    if not isinstance(table, Mapping):
        raise _fail(source, f"data.{name}", table, "expected a table")
    values = dict(table)
    kinds = [k for k in _KINDS if k in values]
    if len(kinds) != 1:
        raise _fail(source, where, sorted(values),
                    "give one of synthetic = SETTING, public = HOUSE, map = MAP")  # fmt: skip
    kind = kinds[0]
    target = values.pop(kind)
    house_seed = values.pop("seed", None)
    if house_seed is not None:
        house_seed = _positive_int(source, f"{where} seed", house_seed, minimum=0)
    seeds = values.pop("seeds", None)
    if seeds is not None:
        seeds = _seeds(source, seeds, f"{where} seeds")
    heldout = values.pop("heldout", kind == "public")
    if not isinstance(heldout, bool):
        raise _fail(source, f"{where} heldout", heldout, "expected true or false")
    if not isinstance(target, str):
        raise _fail(source, f"{where} {kind}", target, "expected text")
    if kind == "synthetic" and target not in SYNTHETIC_FACTORIES:
        raise _fail(source, f"{where} synthetic", target,
                    f"choose one of {sorted(SYNTHETIC_FACTORIES)}")  # fmt: skip
    missing = [k for k in ("height", "width") if k not in values]
    if kind == "synthetic" and target == "scaled" and missing:  # a TypeError's words before
        raise _fail(source, f"{where} synthetic", target,
                    f"a scaled house needs height and width (cells); {' and '.join(missing)} "
                    "not given")  # fmt: skip
    if kind == "public" and values:
        raise _fail(source, where, sorted(values),
                    "a public house takes only heldout and seeds")  # fmt: skip
    if kind == "public" and house_seed is not None:  # it changed nothing, silently
        raise _fail(source, f"{where} seed", house_seed,
                    "a public house is loaded, not drawn: seed changes nothing (its cells' "
                    "seeds choose the held-out trial: seeds = [...])")  # fmt: skip
    data = DataSource(name, kind, target, tuple(values.items()), house_seed, heldout, seeds)
    if not name.strip() or name in (".", "..", "map") or any(c in name for c in "/\\"):
        raise _fail(source, where, name, "a source's name names its house and the report's "
                    "maps_NAME.png: not empty, '.', '..' or 'map', and no '/' or '\\'")  # fmt: skip
    if kind != "public":
        check, known = (
            (data.house_spec, HouseSpec) if kind == "synthetic" else (data.map_tour, MapTour)
        )
        fields = {f.name for f in dataclasses.fields(known)}
        for key, value in values.items():
            if key not in fields:
                hint = did_you_mean(key, sorted(fields))
                why = f"{known.__name__} has no such field; it has {sorted(fields)}{hint}"
                raise _fail(source, f"{where} {key}", value, why)
        problem = _map_tour_problem(values) if kind == "map" else None
        if problem is not None:
            raise _fail(source, f"{where} {problem[0]}", values[problem[0]], problem[1])
        try:
            trials = check().num_trials
        except (TypeError, ValueError) as error:
            key = named_key(str(error), list(values))
            raise StudyError(f"{source}: {where} {dict(values)}: {error}",
                             where + (f" {key}" if key else "")) from None  # fmt: skip
        if heldout and trials < 2:  # each of its cells failed: no trial to fit on
            raise _fail(source, f"{where} heldout", heldout,
                        f"a held-out source needs num_trials >= 2, it has {trials}")  # fmt: skip
    return data


def _map_tour_problem(values: Mapping[str, Any]) -> tuple[str, str] | None:
    """(field, why) for a MapTour value ``simulate_on_map`` refuses or misreads (MapTour checks
    none itself: each cell failed at run time, and ``categories = "kitchen"`` became the letters
    k, i, t, ...), as HouseSpec checks its own; None when all are fine. ``why`` ends with the
    hint to drop the quotes where the field's check would pass the number unquoted."""

    def number(value: object) -> bool:
        return is_number(value) and value == value

    checks = {
        "categories": (lambda v: isinstance(v, list | tuple) and len(v) > 0
                       and all(isinstance(c, str) and c.strip() for c in v),
                       "expected a list of category names"),
        "door_width": (lambda v: v == "auto" or (number(v) and v > 0),
                       "expected 'auto' or metres > 0"),
        "min_room_area": (lambda v: number(v) and v > 0, "expected square metres > 0"),
        "num_trials": (lambda v: _is_int_at_least(v, 1), "expected an integer >= 1"),
        "images_per_room": (lambda v: _is_int_at_least(v, 1), "expected an integer >= 1"),
        "utterances_per_room": (lambda v: _is_int_at_least(v, 0), "expected an integer >= 0"),
        "sentence_fraction": (lambda v: number(v) and 0 <= v <= 1, "expected a share in [0, 1]"),
    }  # fmt: skip
    for name, value in values.items():
        check, why = checks.get(name, (lambda v: True, ""))
        if not check(value):
            return name, why + _quoted_number(value, check)
    return None


def _check_ari_every(source: str, every: int, scoring: str, variants: tuple[Variant, ...]) -> None:
    """A study with ``ari_every`` fits its variants from random labels on the map's own grid
    (:func:`spcopyro.study.evaluate._fit`): no fit keywords, no coarser model grid."""
    if scoring != "study":
        raise _fail(source, "[study] ari_every", every, f"not with scoring = {scoring!r}")
    for variant in variants:
        if variant.fit or variant.spco_settings(None).data.cell_size is not None:
            why = (f"variant {variant.name!r} sets fit keywords or cell_size; the ARI trace is "
                   "kept for fits from random labels on the map's own grid")  # fmt: skip
            raise _fail(source, "[study] ari_every", every, why)


def study_from_dict(values: Mapping[str, Any], *, source: str = "<python>") -> Study:
    """A study from the keys of a study file (module docstring); ``source`` names it in
    errors."""
    unknown = sorted(set(values) - {"study", "variants", "data"})
    if unknown:
        raise _fail(source, "top-level tables", unknown, "expected only [study], [variants.*], "
                    "[data.*]")  # fmt: skip
    head = values.get("study", {})
    if not isinstance(head, Mapping):
        raise _fail(source, "[study]", head, "expected a table")
    extra = sorted(set(head) - _STUDY_KEYS)
    if extra:
        hint = did_you_mean(extra[0], sorted(_STUDY_KEYS))  # close_words, as a variant's keys
        raise _fail(source, f"[study] {extra[0]}", head[extra[0]],
                    f"unknown key; known: {sorted(_STUDY_KEYS)}{hint}")  # fmt: skip
    description = head.get("description", "")
    if not isinstance(description, str):  # description = 3 was kept as the text "3"
        raise _fail(source, "[study] description", description, "expected text (in quotes)")
    name = head.get("name", Path(source).stem if source != "<python>" else "study")
    if not isinstance(name, str) or not name.strip():
        raise _fail(source, "[study] name", name, "expected non-empty text")
    methods = _names(source, "[study] methods", head.get("methods", []),
                     tuple(INFERENCE_METHODS))  # fmt: skip
    baselines = _names(source, "[study] baselines", head.get("baselines", []), BASELINES)
    variants = _variants(source, values.get("variants", {}), methods)
    data_table = values.get("data", {})
    if not isinstance(data_table, Mapping) or not data_table:
        raise _fail(source, "[data]", data_table, "expected at least one [data.NAME] table")
    data = tuple(_data_source(source, str(k), v) for k, v in data_table.items())
    figures: dict[str, str] = {}
    for d in data:  # one's maps figure was drawn over the other's (Small, small: on macOS)
        other = figures.setdefault(maps_file_name(d.name).casefold(), d.name)
        if other != d.name:
            why = (
                f"its report figure {maps_file_name(d.name)} is also [data.{other}]'s "
                f"({maps_file_name(other)}, one file where names ignore case): rename one"
            )
            raise _fail(source, f"[data.{d.name}]", d.name, why)
    scoring = head.get("scoring", "study")
    if scoring not in SCORINGS:
        raise _fail(source, "[study] scoring", scoring, f"choose one of {list(SCORINGS)}")
    if scoring == "comparison":
        kinds = sorted({d.kind for d in data} - {"synthetic", "public"})
        if baselines or head.get("observations_off") or kinds:
            why = "it takes no baselines or observations_off, and synthetic and public houses"
            raise _fail(source, "[study] scoring", scoring, why)
        for variant in variants:  # each of its cells failed at run time
            if variant.fit:
                raise _fail(source, "[study] scoring", scoring,
                            f"it runs the method directly: variant {variant.name!r} sets "
                            f"fit_house keywords {dict(variant.fit)}")  # fmt: skip
    ari_every = head.get("ari_every", 0)
    if ari_every:
        ari_every = _positive_int(source, "[study] ari_every", ari_every)
        _check_ari_every(source, ari_every, scoring, variants)
    if "spcoa_iterations" in head and "C-spcoa" not in baselines:  # it changed nothing
        raise _fail(source, "[study] spcoa_iterations", head["spcoa_iterations"],
                    f"baselines = {list(baselines)} has no C-spcoa row to take it")  # fmt: skip
    sweeps = _sweeps(source, head.get("sweeps", 1000), tuple(v.name for v in variants))
    _check_sweeps_used(source, sweeps, variants, methods)
    if ari_every:  # a trace keeps the ARI every ari_every iterations: none in a shorter fit
        table = dict(sweeps)
        for variant in variants:
            for method in methods or (variant.method,):
                count = table.get(variant.name, table.get(method, table.get("*", 1000)))
                if count < ari_every:
                    raise _fail(source, "[study] ari_every", ari_every,
                                f"variant {variant.name!r} runs {method} for {count} "
                                "iterations: its trace would keep no ARI")  # fmt: skip
    return Study(
        ari_every=int(ari_every),
        scoring=scoring,
        name=name.strip(),
        variants=variants,
        data=data,
        seeds=_seeds(source, head.get("seeds", 1)),
        sweeps=sweeps,
        methods=methods,
        baselines=baselines,
        spcoa_iterations=_positive_int(
            source, "[study] spcoa_iterations", head.get("spcoa_iterations", 100)
        ),
        observations_off=_bool(
            source, "[study] observations_off", head.get("observations_off", False)
        ),  # fmt: skip
        description=description,
        source=source,
    )
