"""The options of ``spcopyro fit`` and their help, as ``spcopyro fit --help`` lists them.

:func:`add_parser` registers ``fit`` on the main parser's subparsers (:mod:`spcopyro.cli.main`).
Registering it imports neither torch, pyro nor numba (``spcopyro --help``, ``fit --help``,
``where``, ``show`` and ``export`` run without torch; ``tests/test_cli_startup.py``); the fit
itself is :mod:`spcopyro.cli.fit`.
"""

from __future__ import annotations

import argparse
import sys

from spcopyro._util.arguments import seed
from spcopyro._util.threads import AUTO, MIN_CELLS_FOR_MORE_THREADS
from spcopyro.cli.common import (
    _PRESET_DEFAULT,
    FIT_SWEEPS,
    MARGINAL_SAMPLES,
    UPDATE_SWEEPS,
    _chain_workers,
    _non_negative_int,
    _positive_int,
    _sweeps,
    _threads,
)
from spcopyro.config import DEFAULT_PRESET, DEFAULT_SNAP_DISTANCE, PRESETS, WORD_WEIGHTINGS
from spcopyro.inference.names import BACKENDS, DEFAULT_METHOD, INFERENCE_METHOD_NAMES, INITS
from spcopyro.results.estimate_names import POINT_ESTIMATES

__all__ = ["add_parser"]


def _run_fit(args: argparse.Namespace) -> int:
    from spcopyro._util.collector import import_frozen

    try:  # torch's and pyro's objects, frozen: the collector does not scan them again (the module)
        fit = import_frozen("spcopyro.cli.fit")
    except KeyboardInterrupt:  # seconds on a cold start: what was stopped, and nothing changed
        from spcopyro.cli.fit_resume import interrupted_before_fit

        print(interrupted_before_fit(args, "importing spcopyro's fit"), file=sys.stderr)
        return 130
    return fit.run_fit(args)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``fit`` (its options and their help, as ``spcopyro fit --help`` lists them).

    Nothing heavy is imported: the choices of ``--backend`` and ``--init`` and the methods
    ``--method`` lists come from :mod:`spcopyro.inference.names` (a method registered at run time
    is checked against the registry when the fit starts)."""
    p = subparsers.add_parser(
        "fit", help="fit SpCoMapping (Gibbs sampling, or --method) and write the semantic map"
    )
    p.add_argument("data", nargs="?", help="house folder (default: the synthetic house)")
    p.add_argument("--out", required=True,
                   help="output folder (written whole at the end; new or empty)")  # fmt: skip
    p.add_argument("--overwrite", action="store_true",
                   help="replace the files an earlier fit wrote in --out (others are "
                   "kept)")  # fmt: skip
    p.add_argument("--resume", metavar="CHECKPOINT",
                   help="continue the interrupted fit saved in CHECKPOINT (OUT.checkpoint.npz; "
                        "Ctrl-C writes it, and an error once the fit has run), with the same data "
                        "and settings; for a finished "
                        "fit of another method than Gibbs (its --chains too), or of --update, "
                        "that Ctrl-C or an error stopped while its outputs were written, write "
                        "them without fitting again "
                        "(default: a new fit)")  # fmt: skip
    p.add_argument("--update", metavar="OUT",
                   help="continue the finished fit in the folder OUT with this data (its old "
                        "and new observations together, e.g. a new trial): its labels, pi and "
                        "distributions start the run, new words get new columns under the "
                        "prior; the map and settings must be the saved fit's (default: a new "
                        "fit)")  # fmt: skip
    p.add_argument("--sweeps", type=_sweeps, default=None,
                   help="Gibbs iterations (the paper's: 5000), or 'auto': run --chains chains "
                        "until split R-hat of the log joint and of the number of concepts < "
                        f"1.05 (at most --max-sweeps); {UPDATE_SWEEPS} with --update; for "
                        "the variational methods a ceiling: they stop once the objective "
                        "settles, changing by less than tolerance x |objective| (cavi, lbp, "
                        "stochastic-vi: tolerance 1e-7 per iteration; svi: 1e-4 between the "
                        "means of windows of 50 steps; --method-option tolerance=0 runs them "
                        "all); for vi-gibbs its Gibbs sweeps, run in full after its CAVI start "
                        "(at most vi_iterations=100, stopping at tolerance 1e-7) "
                        f"(default: {FIT_SWEEPS})")  # fmt: skip
    p.add_argument("--chains", type=_positive_int,
                   help="run this many chains (seeds --seed, --seed + 1, ...) and keep the one of "
                        "highest log joint (default 1; 4 with --sweeps auto)")  # fmt: skip
    p.add_argument("--chain-workers", type=_chain_workers, default=AUTO,
                   help="Gibbs chains advancing at once, each in a process forked from the "
                        "fit on Linux (else on a thread; SPCOPYRO_CHAIN_PROCESSES=off: threads): "
                        "auto (default: one per usable CPU) or N (1: one after another); "
                        "results do not depend on it")  # fmt: skip
    p.add_argument("--anneal-sweeps", type=_non_negative_int, default=0,
                   help="ramp gamma up from gamma/N to gamma over the first N sweeps (burn-in; "
                        "default 0)")  # fmt: skip
    p.add_argument("--max-sweeps", type=_positive_int, default=None,
                   help=f"cap per chain for --sweeps auto (default {FIT_SWEEPS})")  # fmt: skip
    p.add_argument("--preset", choices=sorted(PRESETS), default=DEFAULT_PRESET,
                   help="the model's hyperparameters and data preparation; the options below "
                        "override its values")  # fmt: skip
    p.add_argument("--prior", choices=("dp", "dirichlet"),
                   help="prior of the concept weights pi: weak-limit DP or Dirichlet "
                        f"{_PRESET_DEFAULT}")  # fmt: skip
    p.add_argument("--concepts", type=int,
                   help=f"L, the number (upper bound) of concepts {_PRESET_DEFAULT}")  # fmt: skip
    p.add_argument("--gamma", type=float, help=f"Potts coupling {_PRESET_DEFAULT}")
    p.add_argument("--alpha", type=float,
                   help=f"concentration of the concept weights pi {_PRESET_DEFAULT}")  # fmt: skip
    p.add_argument("--beta", type=float, help=f"word prior concentration {_PRESET_DEFAULT}")
    p.add_argument("--chi", type=float,
                   help=f"image-feature prior concentration {_PRESET_DEFAULT}")  # fmt: skip
    p.add_argument("--concentration", action="append", metavar="NAME=VALUE",
                   help="Dirichlet concentration of a further modality (a modality_NAME.csv of "
                        "the house); repeat for several (default: none)")  # fmt: skip
    p.add_argument("--connectivity", type=int, choices=(4, 8),
                   help=f"MRF neighbourhood of a cell {_PRESET_DEFAULT}")  # fmt: skip
    weighting = p.add_mutually_exclusive_group()
    weighting.add_argument(
        "--word-weighting", choices=WORD_WEIGHTINGS,
        help="words counted as they are, weighted by tf-idf (eq. 20), or auto: tf-idf when at "
             "least 30%% of the utterances are sentences (more than one word), counts "
             "otherwise; config.json records the one used (default: auto; --update: the "
             "updated fit's)",
    )  # fmt: skip
    weighting.add_argument("--tfidf", dest="word_weighting", action="store_const",
                           const="tfidf",
                           help="as --word-weighting tfidf (default: not given)")  # fmt: skip
    p.add_argument(
        "--unobserved-refresh",
        type=float,
        help="share of sweeps that redraw theta/w of concepts without observations (default 1)",
    )
    p.add_argument(
        "--cluster-moves",
        type=float,
        help="share of sweeps that start with a Swendsen-Wang move: whole regions change concept "
        "at once (default 0)",
    )
    p.add_argument(
        "--merge-moves",
        type=float,
        help="share of sweeps that start with a split-merge move: two touching concepts merge "
        "or one splits, parameters integrated out (default: 0.2 for gibbs with --preset coarse "
        "or auto, else 0)",
    )
    p.add_argument(
        "--region-moves",
        type=float,
        help="share of sweeps that start with a region relabel move: a whole region takes a "
        "neighbouring, new or other concept, parameters integrated out (default: the preset's "
        "recommendation for gibbs, else 0)",
    )
    p.add_argument(
        "--refine",
        choices=("auto", "never", "always"),
        default=None,
        help="after a Gibbs fit on model cells coarser than the map: refit on the map's own "
        "cells (images as 100 draws, words at their cell, alpha scaled with the cells) from its "
        "map; auto: where the fit's concepts explain at least half of the images' variance "
        "(default: the preset's recommendation, auto with coarse for a new --method gibbs fit "
        "unless --cell-size, --feature-scaling, --word-scaling, --footprint* or "
        "--word-footprint is given, else never; a not refined line names --method or --update "
        "where it alone keeps coarse from auto). "
        "The refinement's preparation is its own: a --feature-scaling, --word-scaling, "
        "--footprint* or --word-footprint given prepares the first stage only (a note names "
        "those it replaced; "
        "--cell-size map fits with them on the map's own cells). With no model grid coarser "
        "than the map (--cell-size map, a preset without a cell size, or one that rounds to "
        "the map's cells) auto does not refine and always is refused",
    )
    p.add_argument("--point-estimate", choices=POINT_ESTIMATES, default=None,
                   help="the reported map: the highest-log-joint state visited (map-visited) "
                        "or the partition minimising the expected Binder loss (binder) or "
                        "variation of information (vi: a distance between label maps, not "
                        "variational inference) over the --marginal-samples maps, without "
                        "specks (concepts on under 0.5%% of the free cells where under 0.1 "
                        "words were heard: their cells join the concepts that raise the loss "
                        "least; the fit says how many and by how much); binder-specks, "
                        "vi-specks: the minimiser with its specks; writes agreement.png "
                        "(default: vi with --preset coarse or auto for gibbs or vi-gibbs with "
                        "a number of --sweeps, else map-visited)")  # fmt: skip
    p.add_argument("--feature-scaling",
                   help="image features as probability, floor100 or a number s (s * f) "
                        f"{_PRESET_DEFAULT}")  # fmt: skip
    p.add_argument(
        "--init",
        choices=INITS,
        default=None,
        help="starting labels: random, k-means Gaussians, SpCoA pre-learning, or one concept per "
        "room of a geometric room segmentation (default: rooms for a Gibbs fit with --preset "
        "coarse or auto, whose merge moves can split a room; else random)",
    )
    p.add_argument("--init-from", metavar="OUT",
                   help="start from the labels of an earlier fit's output folder on the same map "
                        "(a warm start from any method to any method, e.g. a cavi fit starting "
                        "gibbs; svi keeps 95%% of them, label_smoothing 0.05, and does not "
                        "anneal them, anneal_iterations 0, unless --method-option sets them); "
                        "replaces --init (default: none)")  # fmt: skip
    p.add_argument("--marginal-samples", type=_non_negative_int, default=MARGINAL_SAMPLES,
                   help="gibbs, vi-gibbs: label maps kept over the second half of the sweeps for "
                        "the per-cell probabilities of uncertainty.png (0: none)")  # fmt: skip
    p.add_argument("--seed", type=seed, default=0,
                   help="seed of the sampler (chain k of --chains gets seed + k)")  # fmt: skip
    p.add_argument("--method", metavar="METHOD", default=DEFAULT_METHOD,
                   help=f"inference method: {', '.join(INFERENCE_METHOD_NAMES)}, or one a program "
                        "registered in spcopyro.fit.registry.INFERENCE_METHODS (default: gibbs, "
                        "Algorithm 1)")  # fmt: skip
    p.add_argument("--method-option", action="append", metavar="NAME=VALUE",
                   help="set a field of the method's options, e.g. anneal_iterations=30 (cavi), "
                        "damping=0.5 (lbp), learning_rate=0.05 (svi), block_size=32 "
                        "(stochastic-vi), variational.anneal_iterations=30 (vi-gibbs); "
                        "hyper.alpha=true, hyper.concentrations=true, hyper.gamma=exchange: gibbs "
                        "samples those hyperparameters (gibbs.hyper.alpha=true etc. under "
                        "vi-gibbs); repeat for several (default: the method's defaults; the "
                        "fit's inference line names the options set away from them, "
                        "OUT/config.json records every one)")  # fmt: skip
    p.add_argument("--backend", choices=BACKENDS, default="auto",
                   help="Gibbs sweep implementation: torch (reference), numba (compiled) or "
                        "auto (numba where installed, else torch); the two draw different "
                        "random streams from one seed")  # fmt: skip
    p.add_argument("--snap-distance", type=float, default=DEFAULT_SNAP_DISTANCE,
                   help="metres an observation may be moved onto free space")  # fmt: skip
    p.add_argument("--cell-size", default=None, metavar="METRES",
                   help="the model's grid: fit on cells of about METRES a side (the map "
                        "coarsened, walls kept), or 'map' for the map's own cells "
                        f"{_PRESET_DEFAULT}")  # fmt: skip
    p.add_argument("--word-scaling", type=float, default=None, metavar="S",
                   help="count each utterance's words S times: the words' weight against the "
                        f"images and the MRF {_PRESET_DEFAULT}")  # fmt: skip
    p.add_argument("--footprint", type=float, default=None, metavar="RADIUS",
                   help="observation footprint: spread each observation over the free cells "
                        "within RADIUS metres (geodesic, never through walls), weights summing "
                        "to one observation; 0: its own cell, the paper "
                        f"{_PRESET_DEFAULT}")  # fmt: skip
    p.add_argument(
        "--footprint-kernel",
        choices=("uniform", "gaussian"),
        default=None,
        help="the footprint's weights: uniform (default) or gaussian (sigma = R/2)",
    )
    p.add_argument(
        "--word-footprint",
        type=float,
        default=None,
        metavar="RADIUS",
        help="the utterances' own footprint radius, the images keeping --footprint's: "
        "0 counts each utterance at its own cell (default: --footprint's)",
    )
    p.add_argument(
        "--footprint-fov",
        type=float,
        default=None,
        metavar="DEGREES",
        help="images inform only the cells within +-DEGREES/2 of their yaw (default: the "
        "whole disc)",
    )
    p.add_argument(
        "--footprint-reach-share",
        type=float,
        default=None,
        metavar="E",
        help="spread a share E in [0, 1) of each observation uniformly over its geodesic "
        "Voronoi cell among its modality's observed cells, 1 - E over its footprint; 0: off, "
        f"and the preset's door width with it {_PRESET_DEFAULT}",
    )
    p.add_argument(
        "--footprint-reach-radius",
        type=float,
        default=None,
        metavar="METRES",
        help="cut each observation's Voronoi cell of --footprint-reach-share at METRES "
        "geodesic from its cell (default: no limit)",
    )
    p.add_argument(
        "--footprint-reach-door-width",
        type=float,
        default=None,
        metavar="METRES",
        help="draw the Voronoi cells of --footprint-reach-share within the rooms cut at "
        f"doorways up to METRES wide, as the rooms start cuts them {_PRESET_DEFAULT}",
    )
    p.add_argument("--no-figures", action="store_true",
                   help="write no PNG figures (semantic_map, trace, house, uncertainty, "
                        "agreement), saving seconds and matplotlib's import: labels.npy, "
                        "concepts.json, result.npz, the .npy maps and the printed summary are "
                        "written as always (default: figures written)")  # fmt: skip
    p.add_argument("--threads", type=_threads, default=AUTO,
                   help="torch intra-op threads during the fit: auto (default: one thread unless "
                        f"the map has >= {MIN_CELLS_FOR_MORE_THREADS} free cells and other "
                        "processes leave the cores free), 0 (torch's own setting) or N; results "
                        "do not depend on it")  # fmt: skip
    p.set_defaults(func=_run_fit)
