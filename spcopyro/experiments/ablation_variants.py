"""The variants of the ablation: a variant is a named set of overrides.

A :class:`Variant` holds everything that may differ between two fits of SpCoMapping in the
ablation (:mod:`spcopyro.experiments.ablation`, issue #14 "Evidence required"):

* ``preset``: a name of :data:`spcopyro.config.PRESETS` (the starting values);
* ``settings``: fields of :class:`~spcopyro.config.SpCoConfig` or
  :class:`~spcopyro.config.preparation.DataPreparation` (``gamma``, ``beta``, ``use_words``, a
  footprint radius once the model has one, ...), applied with :func:`spcopyro.config.preset`;
* ``options``: fields of the inference method's options (:class:`~spcopyro.gibbs.GibbsOptions`
  for Gibbs), nested ones by a dotted path (``hyper.alpha``), as ``fit --method-option`` sets
  them (:func:`spcopyro.inference.protocol.with_options`);
* ``fit``: keyword arguments of :func:`spcopyro.fit.house.fit_house` (``chains``, ``init``,
  ``marginal_samples``, a point-estimate option once fit_house has one, ...);
* ``method``: the inference method's name in :mod:`spcopyro.fit.registry` (default ``gibbs``).

Written as text (``--variant`` of ``spcopyro ablation``)::

    NAME:KEY=VALUE,KEY=VALUE,...      e.g.  sw:cluster_moves=0.2,gamma=3.5

An unprefixed KEY is routed by name: ``preset`` and ``method``; a field of SpCoConfig or
DataPreparation; a field (or dotted path) of the method's options; a keyword of ``fit_house``. A
name two of these share must carry a prefix: ``settings.NAME``, ``options.NAME`` or
``fit.NAME``. Values are parsed as the field's current type (bool, int, float, str; ``none``
for None). Every variant is checked when it is made (:class:`VariantError` names the variant,
the key, the value and what was expected), so a typo fails before any fit runs.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from spcopyro.config import DEFAULT_PRESET, PRESETS, DataPreparation, SpCoConfig, SpCoSettings
from spcopyro.config import preset as make_preset
from spcopyro.fit.house import SAMPLERS, fit_house
from spcopyro.fit.registry import get_method
from spcopyro.results.semantic_map import did_you_mean

__all__ = [
    "FIT_RESERVED",
    "OVERRIDE_PREFIXES",
    "Variant",
    "VariantError",
    "make_variant",
    "parse_variant",
]

FIT_RESERVED = frozenset(
    {"house", "settings", "method", "options", "sweeps", "seed", "progress", "threads"}
)
"""fit_house arguments the harness sets itself (a variant may not override them)."""

_SETTING_FIELDS = {f.name for f in dataclasses.fields(SpCoConfig)} | {
    f.name for f in dataclasses.fields(DataPreparation)
}
OVERRIDE_PREFIXES = ("settings", "options", "fit")
"""The prefixes of a variant's keys (``settings.gamma``), in the order :meth:`Variant.describe`
writes them: the ``overrides`` column of a study's table (:mod:`spcopyro.study.maps` reads
them off)."""


class VariantError(ValueError):
    """A variant that cannot be made: an unknown or ambiguous key, or a bad value."""


def _fit_value_problem(key: str, value: object) -> str | None:
    """Why ``value`` is not one fit_house accepts for ``key`` (None: it is, or fit_house checks
    it itself): the named choices and counts, checked when a study is read rather than in every
    cell at run time."""
    from spcopyro.fit.refine import REFINE_MODES
    from spcopyro.inference.names import INITS
    from spcopyro.results.point_estimate import POINT_ESTIMATES

    choices = {"init": INITS, "refine": REFINE_MODES, "point_estimate": POINT_ESTIMATES}
    if key in choices and value not in choices[key]:
        return f"must be one of {list(choices[key])}"
    counts = {"marginal_samples": 0, "chains": 1}
    if key in counts:
        integer = isinstance(value, int) and not isinstance(value, bool)
        if not integer or value < counts[key]:
            return f"must be an integer >= {counts[key]}"
    return None


def fit_combination_problem(fit: Mapping[str, object], method: str) -> str | None:
    """Why fit_house refuses the keywords ``fit`` together, with ``method`` (None: it does not):
    checked when a variant is made (and for each of a study's ``methods``), not in every cell."""
    point_estimate = fit.get("point_estimate", "map-visited")
    if point_estimate != "map-visited" and (
        method not in SAMPLERS or not fit.get("marginal_samples")
    ):
        return (f"point_estimate={point_estimate!r} is computed over the label maps a sampler "
                f"({', '.join(SAMPLERS)}) keeps: it needs marginal_samples > 0 (method "
                f"{method!r}, marginal_samples {fit.get('marginal_samples', 0)})")  # fmt: skip
    refine = fit.get("refine", "never")
    if refine != "never" and method != "gibbs":
        return f"refine={refine!r} refines a Gibbs fit, not method={method!r}"
    return None


def _fit_parameters() -> dict[str, inspect.Parameter]:
    """fit_house's keyword arguments a variant may set (read at call time: new ones count)."""
    parameters = inspect.signature(fit_house).parameters
    return {name: p for name, p in parameters.items() if name not in FIT_RESERVED}


@dataclass(frozen=True)
class Variant:
    """A named set of overrides (see the module docstring). Make one with :func:`make_variant`
    or :func:`parse_variant`, which check it; the fields are tuples of (name, value) pairs so a
    variant is hashable and picklable (it travels to worker processes)."""

    name: str
    preset: str = DEFAULT_PRESET
    method: str = "gibbs"
    settings: tuple[tuple[str, Any], ...] = ()
    options: tuple[tuple[str, Any], ...] = ()
    fit: tuple[tuple[str, Any], ...] = ()

    def spco_settings(self, num_categories: int | None = None, **extra: object) -> SpCoSettings:
        """The model settings; ``num_concepts`` comes from ``num_categories`` when the preset
        needs it (``paper-dirichlet``) and the variant does not set it. ``extra`` (e.g.
        ``use_images=False``) override the variant's own values."""
        values = dict(self.settings)
        if PRESETS[self.preset].get("num_concepts") is None and "num_concepts" not in values:
            values["num_concepts"] = num_categories if num_categories else 6
        values.update(extra)
        return make_preset(self.preset, **values)

    def method_options(self) -> object:
        """The inference method's options with the variant's overrides applied."""
        options = get_method(self.method).default_options()
        for path, value in self.options:
            options = _replace_path(options, path.split("."), value, self.name)
        return options

    def fit_kwargs(self) -> dict[str, Any]:
        """The extra keyword arguments of :func:`spcopyro.fit.house.fit_house`."""
        return dict(self.fit)

    def describe(self) -> str:
        """``NAME:KEY=VALUE,...`` (the text :func:`parse_variant` reads back)."""
        items = []
        if self.preset != DEFAULT_PRESET:
            items.append(f"preset={self.preset}")
        if self.method != "gibbs":
            items.append(f"method={self.method}")
        for prefix, pairs in zip(
            OVERRIDE_PREFIXES, (self.settings, self.options, self.fit), strict=True
        ):
            items += [f"{prefix}.{k}={_text(v)}" for k, v in pairs]
        return f"{self.name}:" + ",".join(items)

    def to_json(self) -> dict[str, object]:
        """The variant as JSON values."""
        return {
            "name": self.name,
            "preset": self.preset,
            "method": self.method,
            "settings": dict(self.settings),
            "options": dict(self.options),
            "fit": dict(self.fit),
        }


def _text(value: object) -> str:
    return (
        "none" if value is None else str(value).lower() if isinstance(value, bool) else str(value)
    )


def _replace_path(options: object, path: list[str], value: object, variant: str) -> object:
    if not dataclasses.is_dataclass(options):
        raise VariantError(
            f"variant {variant!r}: option {'.'.join(path)!r}: {type(options).__name__} has "
            "no fields"
        )
    fields = {f.name for f in dataclasses.fields(options)}
    if path[0] not in fields:
        raise VariantError(
            f"variant {variant!r}: {type(options).__name__} has no field {path[0]!r}; it has "
            f"{sorted(fields)}"
        )
    if len(path) > 1:
        value = _replace_path(getattr(options, path[0]), path[1:], value, variant)
    try:
        return dataclasses.replace(options, **{path[0]: value})  # type: ignore[type-var]
    except (TypeError, ValueError) as error:
        raise VariantError(f"variant {variant!r}: option {path[0]}={value!r}: {error}") from None


def _check_tuning_read(variant: Variant) -> None:
    """VariantError for an option the run would not read: a ``hyper.*`` tuning field (a prior,
    a step) of a hyperparameter the chain does not sample (``hyper.log_gamma_sd`` without
    ``hyper.gamma``), which changed nothing, silently, as ``fit --method-option`` refuses."""
    options = variant.method_options()  # raises VariantError itself
    for key, value in variant.options:
        *parents, last = key.split(".")
        owner = options
        for part in parents:
            owner = getattr(owner, part)
        unused = getattr(owner, "unused", None)
        if callable(unused) and last in unused():
            prefix = ".".join(parents)
            raise VariantError(
                f"variant {variant.name!r}: {key}={value!r}: no hyperparameter the chain samples "
                f"reads {last} ({prefix}.alpha, {prefix}.concentrations and {prefix}.gamma choose "
                "them): set the one it tunes, or leave it out"
            )


def _parse_text(text: str, current: object, where: str) -> object:
    """``text`` as a value of ``current``'s type; untyped (None) defaults read as a number,
    true/false, none, or else the text."""
    lowered = text.strip().lower()
    if lowered in ("none", "null"):
        return None
    if isinstance(current, bool) or (current is None and lowered in ("true", "false")):
        if lowered in ("true", "1", "yes", "on"):
            return True
        if lowered in ("false", "0", "no", "off"):
            return False
        raise VariantError(f"{where}: expected true or false, got {text!r}")
    if isinstance(current, int) or current is None:
        try:
            return int(text)
        except ValueError:
            if isinstance(current, int) and not isinstance(current, float):
                try:  # an int field given 3.0 or 1e3: accept whole numbers
                    number = float(text)
                except ValueError:
                    raise VariantError(f"{where}: expected an integer, got {text!r}") from None
                if math.isfinite(number) and number == int(number):
                    return int(number)
                raise VariantError(f"{where}: expected an integer, got {text!r}") from None
    if isinstance(current, float | int) or current is None:
        try:
            return float(text)
        except ValueError:
            if current is not None:
                raise VariantError(f"{where}: expected a number, got {text!r}") from None
    if isinstance(current, str):  # a text field that also takes a number (feature_scaling)
        try:
            return float(text)
        except ValueError:
            pass
    return text.strip()


def _option_default(options: object, path: list[str]) -> tuple[bool, object]:
    """(whether ``path`` names a field of the options, its current value)."""
    current = options
    for part in path:
        if not dataclasses.is_dataclass(current):
            return False, None
        if part not in {f.name for f in dataclasses.fields(current)}:
            return False, None
        current = getattr(current, part)
    return True, current


def _option_paths(options: object, prefix: str = "") -> list[str]:
    """Every field of the options as :func:`_option_default` reads it, nested ones as
    ``a.b`` (the candidates of a misspelt option's suggestion)."""
    paths = []
    for f in dataclasses.fields(options):  # type: ignore[arg-type]
        paths.append(prefix + f.name)
        value = getattr(options, f.name)
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            paths += _option_paths(value, f"{prefix}{f.name}.")
    return paths


def _setting_default(name: str) -> object:
    for layer in (SpCoConfig(), DataPreparation()):
        if hasattr(layer, name):
            return getattr(layer, name)
    raise KeyError(name)


def make_variant(name: str, overrides: Mapping[str, object] | None = None) -> Variant:
    """A checked :class:`Variant` named ``name`` from ``{KEY: VALUE}`` (see the module
    docstring for the keys; a VALUE given as text is parsed as its field's type).

    Raises :class:`VariantError` for an empty or malformed name, an unknown or ambiguous key, a
    value of the wrong type, or settings / options / fit arguments that do not validate.
    """
    if not isinstance(name, str) or not name.strip() or any(c in name for c in ":,="):
        raise VariantError(f"variant name {name!r}: must be non-empty text without ':', ',' or '='")
    name = name.strip()
    overrides = dict(overrides or {})
    preset_name = str(overrides.pop("preset", DEFAULT_PRESET))
    if preset_name not in PRESETS:
        raise VariantError(
            f"variant {name!r}: preset={preset_name!r}: choose one of {sorted(PRESETS)}"
        )
    method = str(overrides.pop("method", "gibbs"))
    try:
        default_options = get_method(method).default_options()
    except (KeyError, ValueError) as error:
        raise VariantError(f"variant {name!r}: method={method!r}: {error}") from None
    fit_parameters = _fit_parameters()
    settings: dict[str, object] = {}
    options: dict[str, object] = {}
    fit: dict[str, object] = {}
    for key, value in overrides.items():
        where = f"variant {name!r}: {key}={value!r}"
        prefix, dot, rest = key.partition(".")
        if dot and prefix in OVERRIDE_PREFIXES:
            targets = [prefix]
            key = rest
        else:
            targets = []
            if key in _SETTING_FIELDS:
                targets.append("settings")
            if _option_default(default_options, key.split("."))[0]:
                targets.append("options")
            if key in fit_parameters:
                targets.append("fit")
            if len(targets) > 1:
                raise VariantError(
                    f"{where}: {key!r} is a field of {' and '.join(targets)}; write "
                    + " or ".join(f"{t}.{key}" for t in targets)
                )
            if not targets and key in FIT_RESERVED:
                raise VariantError(
                    f"{where}: {key!r} is set by the ablation itself (its --sweeps, seeds, "
                    "threads), not by a variant"
                )
            if not targets:
                known_options = [f.name for f in dataclasses.fields(default_options)]  # type: ignore[arg-type]
                setting_fields = sorted(_SETTING_FIELDS)
                option_paths = _option_paths(default_options)
                known = [*setting_fields, *option_paths, *fit_parameters]
                if dot:  # a misspelt prefix ('setings.gamma'): the prefixed keys are close
                    known += [f"settings.{k}" for k in setting_fields]
                    known += [f"options.{k}" for k in option_paths]
                    known += [f"fit.{k}" for k in fit_parameters]
                hint = did_you_mean(key, ["preset", "method", *known])
                raise VariantError(
                    f"{where}: unknown key {key!r}. Known: preset, method; settings "
                    f"{setting_fields}; {method} options {sorted(known_options)} "
                    f"(nested ones as a.b); fit_house arguments {sorted(fit_parameters)}{hint}"
                )
        target = targets[0]
        if target == "settings":
            if key not in _SETTING_FIELDS:
                hint = did_you_mean(key, sorted(_SETTING_FIELDS), "settings.")
                raise VariantError(
                    f"{where}: SpCoConfig / DataPreparation have no field {key!r}{hint}"
                )
            if isinstance(value, str):
                value = _parse_text(value, _setting_default(key), where)
            settings[key] = value
        elif target == "options":
            found, default = _option_default(default_options, key.split("."))
            if not found:
                hint = did_you_mean(key, _option_paths(default_options), "options.")
                raise VariantError(
                    f"{where}: {type(default_options).__name__} has no field (path) {key!r}{hint}"
                )
            if isinstance(value, str) and not isinstance(default, str):
                value = _parse_text(value, default, where)
            options[key] = value
        else:
            if key not in fit_parameters:
                raise VariantError(
                    f"{where}: fit_house has no argument {key!r} a variant may set; it has "
                    f"{sorted(fit_parameters)} ({sorted(FIT_RESERVED)} are the harness's own)"
                    + did_you_mean(key, sorted(fit_parameters), "fit.")
                )
            default = fit_parameters[key].default
            if default is inspect.Parameter.empty:
                default = None
            if isinstance(value, str) and not isinstance(default, str):
                value = _parse_text(value, default, where)
            problem = _fit_value_problem(key, value)
            if problem:
                raise VariantError(f"{where}: fit_house's {key} {problem}")
            fit[key] = value
    variant = Variant(
        name, preset_name, method, tuple(settings.items()), tuple(options.items()),
        tuple(fit.items()),
    )  # fmt: skip
    try:
        variant.spco_settings(num_categories=6)
    except (TypeError, ValueError) as error:
        raise VariantError(f"variant {name!r}: settings {settings}: {error}") from None
    _check_tuning_read(variant)  # raises VariantError itself
    try:
        inspect.signature(fit_house).bind_partial(**fit)
    except TypeError as error:
        raise VariantError(f"variant {name!r}: fit arguments {fit}: {error}") from None
    problem = fit_combination_problem(fit, method)
    if problem:  # each of its cells failed at run time
        raise VariantError(f"variant {name!r}: {problem}")
    return variant


def parse_variant(text: str) -> Variant:
    """A variant from ``NAME:KEY=VALUE,KEY=VALUE`` (``NAME`` alone: the default preset)."""
    if not isinstance(text, str):
        raise VariantError(f"variant {text!r}: expected text NAME:KEY=VALUE,...")
    name, _, body = text.partition(":")
    overrides: dict[str, object] = {}
    for item in body.split(","):
        item = item.strip()
        if not item:
            continue
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise VariantError(f"variant {text!r}: {item!r} is not KEY=VALUE")
        if key.strip() in overrides:
            raise VariantError(f"variant {text!r}: {key.strip()!r} is given twice")
        overrides[key.strip()] = value.strip()
    return make_variant(name, overrides)
