"""Warnings, with the reason, for legal but extreme model settings: gamma below the Potts critical
coupling (no regions form) or at the freezing point of the Gibbs sampler, and concentrations
outside what float64 resolves in the log joint; and for data preparation settings that do
nothing (a footprint's kernel or field of view without a footprint).

:func:`spcopyro.fit.house.prepare_model_data` logs them (logger ``"spcopyro"``), so every fit,
``spcopyro fit`` included, says them; they depend on the settings only, and on whether the fit
samples (those about the Gibbs sampler are given to gibbs and vi-gibbs only). The warnings on
a fit's map, which read its result, are in :mod:`spcopyro.fit.map_warnings`.
"""

from __future__ import annotations

from spcopyro._util.messages import setting
from spcopyro.config import CONCENTRATION_FIELDS, DataPreparation, SpCoConfig

FREEZING_GAMMA = 10.0
"""gamma at and above which the sampler freezes: measured from random labels on the synthetic
house of seed 0 (3600 free cells, L = 120, 1000 sweeps), gamma 4 ended with 16 concepts, 8 with
83 (paper-dp; 54 with original-code), 10 with 111 (89), and 12 to 30 with 117 of 120, no concept
vanishing after sweep 200 (106 with original-code): a domain wall moves only at a cost of about
exp(-gamma) per flip, so the random start's patches stay."""
CONCENTRATION_RANGE = (1e-3, 1e12)
"""alpha, chi, beta and further concentrations outside this range make the log joint rounding
noise or dominated by empty concepts' parameters (see :func:`config_warnings`)."""


def gamma_warning(config: SpCoConfig) -> str | None:
    """A warning when gamma is below the Potts critical coupling ln(1 + sqrt(L)), else None.

    That value is the 4-neighbour square lattice's; with 8 neighbours every cell has twice the
    bonds and regions form at a weaker coupling (the 05 notebook fits gamma 1.5 with L = 30 at
    ARI 0.97), so no warning is given there."""
    if config.connectivity != 4 or config.gamma >= config.critical_gamma:
        return None
    return (
        f"gamma = {config.gamma:g} is below the Potts critical coupling ln(1 + sqrt(L)) = "
        f"{config.critical_gamma:.3f} for L = {config.num_concepts}: the MRF will not form "
        f"regions (labels stay in patches of a few cells); raise {setting('gamma', '--gamma')} "
        f"or lower {setting('num_concepts', '--concepts')}"
    )


def freezes(config: SpCoConfig) -> bool:
    """Whether gamma is at or above :data:`FREEZING_GAMMA`, where the Gibbs sampler freezes in
    its random start's patches (:func:`config_warnings` warns a sampled fit)."""
    return config.gamma >= FREEZING_GAMMA


def config_warnings(config: SpCoConfig, sampled: bool = True) -> list[str]:
    """Warnings, with the reason, for legal but extreme model settings (empty if none).
    ``sampled``: the fit samples (gibbs, vi-gibbs); False leaves out the warnings that concern
    the Gibbs sampler only (freezing gamma, concentrations), which were noise for
    ``--method cavi`` or ``lbp``.

    * gamma below the Potts critical coupling ln(1 + sqrt(L)) (:func:`gamma_warning`): no
      regions form;
    * gamma >= :data:`FREEZING_GAMMA`: the sampler freezes in its starting patches;
    * a concentration a (alpha, chi, beta or a further modality's) above 1e12: the log joint
      holds (a - 1) sum log phi, of order a L K log K, which float64 resolves to 2^-52 of
      itself; measured on a small house, the log joint jumped by 4e3 nats between sweeps at
      chi = 1e15 (300 at 1e12) and was meaningless (1e19 to 1e289) from 1e20 on;
    * a concentration below 1e-3: an empty concept's parameters are drawn from Dir(a), with
      log phi of order -1/a, and the term (a - 1) sum log phi of order L K / a swamps the data
      terms; the log joint then follows those draws, not the map (measured: it swung between
      sweeps by 2e4-5e4 nats at 3e-3 against 400 at 0.1-10, and was 1e302 at 1e-300).

    In both concentration cases the Gibbs sampler's trace and its choice of the best sweep mean
    nothing (the warnings say so by name: a variational method's objective holds no drawn
    parameters). Only the first item concerns every method.
    """
    warnings = [w for w in (gamma_warning(config),) if w]
    if not sampled:
        return warnings
    if freezes(config):
        critical = f"{config.critical_gamma:.2f}" if config.connectivity == 4 else "coupling"
        warnings.append(
            f"gamma = {config.gamma:g} is at or above {FREEZING_GAMMA:g}, where the Gibbs "
            "sampler freezes: a domain wall moves only at a cost of about exp(-gamma) per cell, "
            "so labels stay in the random start's patches (measured: gamma 12 to 30 kept 117 of "
            "120 concepts over 1000 sweeps; not the variational methods: cavi and lbp at 12 kept "
            f"21 and 9 on the synthetic house); lower {setting('gamma', '--gamma')}: regions "
            f"form just above the critical {critical}"
            # no closed form for 8 neighbours: SpCoConfig.critical_gamma
        )
    low, high = CONCENTRATION_RANGE
    fields = ("alpha", *CONCENTRATION_FIELDS.values())
    concentrations = [(name, getattr(config, name)) for name in fields]
    concentrations += [(f"concentration {n!r}", v) for n, v in config.concentrations]
    for name, value in concentrations:
        if value > high:
            warnings.append(
                f"{name} = {value:g} is above {high:g}: the log joint's prior term (a - 1) "
                "sum log phi grows beyond what float64 resolves to 1 nat, so the Gibbs sampler's "
                "log joint per sweep and its choice of the best sweep become rounding noise"
            )
        elif value < low:
            warnings.append(
                f"{name} = {value:g} is below {low:g}: concepts without data draw parameters "
                f"with log values of order -1/{name} and the Gibbs sampler's log joint follows "
                "those draws, not the map; its log joint per sweep and choice of the best sweep "
                "mean nothing"
            )
    return warnings


def preparation_warnings(data: DataPreparation) -> list[str]:
    """Warnings for data preparation settings that do nothing (empty if none): a footprint
    kernel other than the default ``"uniform"`` without any footprint
    (:attr:`~spcopyro.config.preparation.DataPreparation.has_footprint`: the words' own reads it
    too), or a field of view with ``footprint_radius`` 0 (it applies to images only, words always
    using the disc), where the observations it would weight count in their own cell only and it is
    not read (the fit's counts are as if it were not given)."""
    given = []
    if data.footprint_kernel != "uniform" and not data.reads("footprint_kernel"):
        given.append(setting(f"footprint_kernel={data.footprint_kernel!r}",
                             f"--footprint-kernel {data.footprint_kernel}"))  # fmt: skip
    if data.footprint_fov is not None and not data.reads("footprint_fov"):
        given.append(setting(f"footprint_fov={data.footprint_fov:g}",
                             f"--footprint-fov {data.footprint_fov:g}"))  # fmt: skip
    if not given:
        return []
    it = "it takes" if len(given) == 1 else "they take"
    where = "each observation counts in its own cell only"
    if data.has_footprint:  # the words' own footprint, which has no field of view
        where = "each image counts in its own cell only (the words' own footprint is a disc)"
    return [
        f"{' and '.join(given)} {'does' if len(given) == 1 else 'do'} nothing without a "
        f"footprint: footprint_radius is 0, so {where}; "
        f"{it} effect with {setting('footprint_radius=R', '--footprint R')}, R metres > 0"
    ]
