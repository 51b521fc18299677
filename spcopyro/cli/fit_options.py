"""``spcopyro fit``'s inference options from its command line: ``--method-option NAME=VALUE``
for any method, and the Gibbs sampler's own flags (``--backend``, ``--anneal-sweeps``, the move
rates) for the methods that run the sampler: ``gibbs``, and ``vi-gibbs`` after its CAVI. Under
another method those flags are refused, naming them (they were ignored silently)."""

from __future__ import annotations

import argparse
import dataclasses

from spcopyro.cli.common import given as given_flag
from spcopyro.inference.names import SAMPLERS as SAMPLERS  # re-exported: sweeps, marginals
from spcopyro.inference.protocol import StartDependentOptions, options_for_start

__all__ = ["SAMPLERS", "check_sweeps", "given_start", "method_options", "warm_start_kept"]


def _given_gibbs_flags(args: argparse.Namespace) -> dict[str, tuple[str, object]]:
    """The Gibbs flags the command line set: GibbsOptions field -> (flag, value)."""
    given = {
        "backend": ("--backend", args.backend, "auto"),
        "anneal_sweeps": ("--anneal-sweeps", args.anneal_sweeps, 0),
        "unobserved_refresh": ("--unobserved-refresh", args.unobserved_refresh, None),
        "cluster_moves": ("--cluster-moves", args.cluster_moves, None),
        "merge_moves": ("--merge-moves", args.merge_moves, None),
        "region_moves": ("--region-moves", args.region_moves, None),
    }
    return {name: (flag, value) for name, (flag, value, unset) in given.items() if value != unset}


def _check_q_start(args: argparse.Namespace, options: object | None) -> None:
    """ValueError for ``--method-option init=soft`` (``variational.init=soft``), q's random
    start, with start labels (``--init`` other than random, ``--init-from``, ``--update``'s
    saved labels), which replace it: soft was ignored silently."""
    variational = getattr(options, "variational", options)
    start = f"--init-from {args.init_from}" if args.init_from is not None else None
    if getattr(args, "update", None) is not None:
        start = f"--update {args.update}"
    if getattr(args, "init", None) not in (None, "random"):
        start = f"--init {args.init}"
    if getattr(variational, "init", None) == "soft" and start is not None:
        name = "variational.init" if variational is not options else "init"
        raise ValueError(
            f"--method-option {name}=soft draws q(C) at random, but {start} starts from labels "
            "(q one-hot on them): pass one of the two"
        )


def _check_clip_norm(args: argparse.Namespace, options: object | None) -> None:
    """ValueError for svi's ``clip_norm`` set with an optimiser that does not clip (``adam``,
    the default): it was ignored silently."""
    names = {a.partition("=")[0].strip() for a in args.method_option or []}
    if "clip_norm" in names and getattr(options, "optimiser", None) == "adam":
        raise ValueError(
            "--method-option clip_norm clips the gradients of optimiser=clipped-adam; with adam "
            "(the default) it does nothing: add --method-option optimiser=clipped-adam"
        )


def _check_hyper_tuning(args: argparse.Namespace, sampler: object) -> None:
    """ValueError for a ``hyper.*`` tuning option of a hyperparameter the chain does not
    sample (``hyper.log_gamma_sd=2`` without ``hyper.gamma``): it was ignored silently."""
    prefix = "gibbs.hyper." if args.method == "vi-gibbs" else "hyper."
    unused = set(sampler.hyper.unused())  # type: ignore[attr-defined]
    for assignment in args.method_option or []:
        name = assignment.partition("=")[0].strip()
        if name.startswith(prefix) and name[len(prefix) :] in unused:
            raise ValueError(
                f"--method-option {assignment}: no hyperparameter the chain samples reads "
                f"{name[len(prefix) :]} ({prefix}alpha, {prefix}concentrations and "
                f"{prefix}gamma choose them): set the one it tunes, or leave it out"
            )


def _check_twice_set(args: argparse.Namespace, given: dict[str, tuple[str, object]]) -> None:
    """ValueError for a Gibbs flag and a ``--method-option`` setting the same field (gibbs's
    ``cluster_moves``, vi-gibbs's ``gibbs.cluster_moves``): gibbs took the option's value,
    vi-gibbs the flag's, silently. A move rate the preset filled in is not the user's: the
    option overrides it."""
    if args.method not in SAMPLERS:
        return  # the flags are refused there
    prefix = "gibbs." if args.method == "vi-gibbs" else ""
    filled = getattr(args, "preset_filled", set())  # by fit_settings.apply_preset_inference
    for assignment in args.method_option or []:
        name = assignment.partition("=")[0].strip()
        field = name[len(prefix) :] if name.startswith(prefix) else None
        if field in given and field not in filled:
            flag, value = given[field]
            raise ValueError(
                f"{flag} {value} and --method-option {assignment} set the same option: pass one"
            )


def check_sweeps(args: argparse.Namespace) -> None:
    """ValueError for ``--sweeps``, ``--max-sweeps`` and ``--chains`` that contradict each
    other or ``--method`` (each was ignored silently or failed deep in the library)."""
    if args.sweeps == "auto" and args.method != "gibbs":
        raise ValueError(f"--sweeps auto is Gibbs' convergence rule, not one of --method "
                         f"{args.method}: give a number of --sweeps")  # fmt: skip
    if args.sweeps == "auto" and args.chains is not None and args.chains < 2:
        raise ValueError(f"--sweeps auto compares chains (split R-hat): --chains {args.chains} "
                         "cannot; give 2 or more, or a number of --sweeps")  # fmt: skip
    if args.max_sweeps is not None and args.sweeps != "auto":  # it was ignored silently
        raise ValueError(f"--max-sweeps caps --sweeps auto, not --sweeps {args.sweeps}: leave "
                         "it out")  # fmt: skip


def backend_used(options: object, config: object) -> str | None:
    """The backend a fit with ``options`` runs (``auto`` resolved), for the "backend used"
    line: Gibbs's, CAVI's, loopy BP's (torch where gamma D > 300), memoized VI's, vi-gibbs's
    two; None for a method without one (svi). Only Gibbs fits printed it, though config.json's
    ``inference.backend_used`` is said to be printed too."""
    from spcopyro.gibbs.backends import get_backend
    from spcopyro.gibbs.options import GibbsOptions

    if isinstance(options, GibbsOptions):  # before the variational methods' imports
        return get_backend(options.backend).name
    from spcopyro.guides.lbp_method import LBPOptions
    from spcopyro.guides.memoized import StochasticOptions, compiled_path
    from spcopyro.guides.options import VariationalOptions
    from spcopyro.guides.run import resolve_backend
    from spcopyro.guides.vi_gibbs import VIGibbsOptions

    if isinstance(options, VariationalOptions):
        return resolve_backend(options.backend)
    if isinstance(options, VIGibbsOptions):
        cavi = resolve_backend(options.variational.backend)
        return f"{cavi} (CAVI), {get_backend(options.gibbs.backend).name} (Gibbs)"
    if isinstance(options, StochasticOptions):
        return "torch" if compiled_path(options.backend) is None else "numba"
    if isinstance(options, LBPOptions):
        ran = resolve_backend(options.backend)  # where numba imports; auto: not at a large gamma D
        if ran == "numba" and options.backend == "auto":
            from spcopyro.guides.numba_lbp import usable_at

            gamma, degree = config.gamma, config.connectivity  # type: ignore[attr-defined]
            return ran if usable_at(gamma, degree) else "torch"
        return ran
    return None


def warm_start_kept(options: object) -> str:
    """What of a warm start's labels (``--init-from``, ``--update``) a method keeps, for the
    "starting from" line: svi smooths them toward uniform by ``label_smoothing`` (unset: 0.05
    for given labels, which keeps 95 %; until 2026-12-05 it was 0.9, which kept 10 % and at
    L = 120 fell to the uniform fixed point) and anneals gamma from 0 over
    ``anneal_iterations`` steps (unset: 0 for given labels; until 2026-12-05 it was 100, which
    lost them at L = 120 too); "" for a method that starts at them."""
    if not isinstance(options, StartDependentOptions):  # svi's SVIOptions are
        return ""
    ran = options_for_start(options, given_start=True)
    smoothing, anneal = ran.label_smoothing, ran.anneal_iterations
    if getattr(options, "label_smoothing", None) is None:
        how = "the default for given labels"
    elif smoothing > 0.05:
        how = "as set; left unset, 0.05 keeps 95%"
    else:
        how = "as set"
    if anneal:  # from gamma 0 the unobserved cells drift to uniform (at L = 120 q ended flat)
        how += (f"; gamma annealed from 0 over {anneal} steps, as set, can still lose them: "
                "left unset, given labels are not annealed")  # fmt: skip
    return (
        f" ({1 - smoothing:.0%} of its labels in q's start: label_smoothing {smoothing:g}, {how})"
    )


def given_start(args: argparse.Namespace) -> bool:
    """Whether the fit starts from labels (``--init-from``, ``--update``'s saved fit, ``--init``
    other than random), not a random start: what svi's options left unset depend on."""
    starts_at = (getattr(args, "init_from", None), getattr(args, "update", None))
    return any(x is not None for x in starts_at) or getattr(args, "init", None) not in (
        None, "random"
    )  # fmt: skip


def method_options(args: argparse.Namespace) -> object | None:
    """The options ``fit`` runs ``args.method`` with (None: the method's defaults).

    ``gibbs``: :class:`~spcopyro.gibbs.options.GibbsOptions` from the flags (a move rate left
    unset is 0; ``fit_settings.apply_preset_inference`` filled the preset's first), then
    ``--method-option``. ``vi-gibbs``: its options from ``--method-option``, with the Gibbs
    flags given set on its ``gibbs`` part. Any other method: ValueError if a Gibbs flag or
    ``--marginal-samples`` was given. ValueError for ``--backend numba`` without numba, before
    anything is written."""
    from spcopyro.fit.registry import INFERENCE_METHODS
    from spcopyro.gibbs.backends import get_backend
    from spcopyro.gibbs.options import GibbsOptions
    from spcopyro.inference.protocol import with_options

    given = _given_gibbs_flags(args)
    if given and args.method not in SAMPLERS:
        flags = ", ".join(f"{flag} {value}" for flag, value in given.values())
        raise ValueError(
            f"{flags}: options of the Gibbs sampler, which --method {args.method} does not run "
            "(gibbs and vi-gibbs do); leave them out"
        )
    _check_twice_set(args, given)
    if getattr(args, "chain_workers", "auto") != "auto" and args.method != "gibbs":
        raise ValueError(
            f"--chain-workers {args.chain_workers}: Gibbs chains advancing at once; --method "
            f"{args.method}'s fits run one after another: leave it out"
        )
    if given_flag(args.marginal_samples) and args.method not in SAMPLERS:
        raise ValueError(
            f"--marginal-samples {args.marginal_samples}: label maps of a sampler's sweeps "
            f"(gibbs and vi-gibbs); --method {args.method} gives q(C_i), which uncertainty.png "
            "shows: leave it out"
        )
    if args.method == "gibbs":
        unset_moves = {"unobserved_refresh": 1.0, "cluster_moves": 0.0, "merge_moves": 0.0,
                       "region_moves": 0.0}  # fmt: skip
        fields = {**unset_moves, **{name: value for name, (_, value) in given.items()}}
        options = with_options(GibbsOptions(**fields), args.method_option or [])
        sampler = options
    else:
        default = INFERENCE_METHODS[args.method].default_options()
        options = with_options(default, args.method_option) if args.method_option else None
        _check_q_start(args, options)
        _check_clip_norm(args, options)
        if args.method != "vi-gibbs":
            return options
        base = default if options is None else options
        fields = {name: value for name, (_, value) in given.items()}
        options = dataclasses.replace(base, gibbs=dataclasses.replace(base.gibbs, **fields))
        sampler = options.gibbs
    _check_hyper_tuning(args, sampler)
    try:
        get_backend(sampler.backend)
    except ImportError as error:  # --backend numba without numba
        raise ValueError(str(error)) from None
    return options
