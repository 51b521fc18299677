"""The Gibbs sampler's own options: which backend, and the moves and schedules composed with
Algorithm 1's sweep (none of them changes the model; see :class:`~spcopyro.config.SpCoConfig`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from spcopyro._util.number_checks import is_number
from spcopyro.gibbs.anneal import check_anneal_sweeps
from spcopyro.gibbs.hyper_options import HyperparameterOptions, as_hyper_options
from spcopyro.inference.names import BACKENDS


@dataclass(frozen=True)
class GibbsOptions:
    """How the Gibbs sampler runs.

    Attributes:
        backend: ``"torch"`` (the readable reference), ``"numba"`` (compiled, same distribution;
            needs the optional ``numba`` package) or ``"auto"`` (numba when installed). The two
            draw different random streams from the same seed: a seeded run reproduces bit for
            bit on one backend only.
        unobserved_refresh: the probability that a sweep redraws theta_l and w_l of the concepts
            that hold no observed cell (for them the conditional is the prior). 1.0 (default)
            redraws every concept every sweep, as Algorithm 1 does; any value in (0, 1] leaves
            the posterior invariant (a random choice of which conditionally independent blocks
            to update, made independently of the state), and a small one makes the sweep's
            cost nearly flat in L, since the [L, K] and [L, V] draws dominate for large L.
        cluster_moves: the probability that a sweep starts with a Swendsen-Wang cluster move of
            the labels (:mod:`spcopyro.gibbs.cluster`: whole regions change concept at once).
            0 (default): Algorithm 1's single-site sweeps only. Any value in [0, 1] leaves the
            posterior invariant (the choice is made independently of the state).
        merge_moves: the probability that a sweep starts with a split-merge move
            (:mod:`spcopyro.gibbs.merge`: two touching concepts merge, or one splits in two, by
            Metropolis-Hastings with pi, theta and w integrated out). 0 (default): none. Any
            value in [0, 1] leaves the posterior invariant.
        region_moves: the probability that a sweep starts with a region relabel move
            (:mod:`spcopyro.gibbs.region_move`: one Swendsen-Wang cluster takes another concept,
            a neighbouring one, a new one or another in use, by Metropolis-Hastings with pi,
            theta and w integrated out; it merges a room carried by two concepts). 0 (default):
            none. Any value in [0, 1] leaves the posterior invariant.
        anneal_sweeps: ramp the labels' coupling gamma up over the first ``anneal_sweeps``
            sweeps of a chain (:mod:`spcopyro.gibbs.anneal`); those sweeps are burn-in.
        hyper: which hyperparameters (alpha, the concentrations, gamma) the chain samples
            (:class:`~spcopyro.gibbs.hyper_options.HyperparameterOptions`; none by default).
    """

    backend: str = "auto"
    unobserved_refresh: float = 1.0
    cluster_moves: float = 0.0
    anneal_sweeps: int = 0
    merge_moves: float = 0.0
    hyper: HyperparameterOptions = HyperparameterOptions()
    region_moves: float = 0.0

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ValueError:
            return ValueError(f"GibbsOptions.{name}={getattr(self, name)!r}: {why}")

        if self.backend not in BACKENDS:
            raise bad("backend", f"choose one of {BACKENDS}")
        refresh = self.unobserved_refresh
        if not (is_number(refresh) and 0.0 < refresh <= 1.0):
            raise bad("unobserved_refresh", "must be a probability in (0, 1]")
        moves = self.cluster_moves
        if not (is_number(moves) and 0.0 <= moves <= 1.0):
            raise bad("cluster_moves", "must be a probability in [0, 1]")
        merges = self.merge_moves
        if not (is_number(merges) and 0.0 <= merges <= 1.0):
            raise bad("merge_moves", "must be a probability in [0, 1]")
        regions = self.region_moves
        if not (is_number(regions) and 0.0 <= regions <= 1.0):
            raise bad("region_moves", "must be a probability in [0, 1]")
        object.__setattr__(self, "anneal_sweeps", check_anneal_sweeps(self.anneal_sweeps))
        object.__setattr__(self, "hyper", as_hyper_options(self.hyper))

    def replace(self, **changes: object) -> GibbsOptions:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)
