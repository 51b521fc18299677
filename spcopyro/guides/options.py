"""Options of the variational methods (CAVI, loopy BP), kept beside them as Gibbs' are."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Literal

from spcopyro._util.number_checks import is_finite_number, is_int, is_number
from spcopyro.guides.factors import PiFamily


@dataclass(frozen=True)
class VariationalOptions:
    """How coordinate-ascent variational inference runs.

    Attributes:
        anneal_iterations: gamma rises linearly to the model's value over this many
            iterations, iteration s at gamma min(1, (s + 1) / A) as Gibbs' ``anneal_sweeps``
            (:func:`spcopyro.inference.schedule.annealed_gamma`; 0: no annealing, the default).
            Mean field started at full coupling freezes near the first labelling it sees;
            starting uncoupled lets the observations place their concepts first, but with many
            concepts (L = 120) a q annealed from gamma = 0 stays in mean field's disordered
            fixed point, stable up to gamma = L / D (:mod:`spcopyro.guides.cavi`). The ELBO
            only rises monotonically once gamma is at its value.
        damping: each block's new q(C_i) is mixed with the old one,
            ``q <- (1 - damping) q_new + damping q_old`` (0: exact coordinate ascent, which never
            lowers the ELBO; > 0 gives that up to calm oscillations).
        pi_family: q(pi) as the model states it (``"dirichlet"``) or the truncated stick-breaking
            DP (``"stick-breaking"``, a different prior: see :mod:`spcopyro.guides.factors`).
        tolerance: stop once an iteration at full gamma changes the ELBO by less than
            ``tolerance * |ELBO|`` (:func:`spcopyro.inference.schedule.converged`; 0: run every
            iteration); the iterations asked for are then a ceiling.
        backend: ``"torch"`` (the dense reference), ``"numba"`` (the compiled sparse update of
            :mod:`spcopyro.guides.numba_cavi`) or ``"auto"`` (numba where it imports).
        init: the start when no labels are given: ``"one-hot"`` (uniformly random labels, each
            cell's q all on one concept) or ``"soft"`` (each q(C_i) a Dir(1) draw over the L
            concepts: no cell is committed yet).
        support: the numba backend keeps at most this many concepts per cell (0: all L, no
            cap). Top-K truncation alone never lowers the ELBO (see that module), but it changes
            what mean field finds: a cell near disorder spreads its mass over all L concepts, and
            cutting it to K behaves like a K-state Potts model (it orders at a lower gamma).
        threshold: the numba backend also drops a cell's concepts with mass below this (0: keep
            all K); an iteration then lowers the ELBO by at most sum_i -log(1 - dropped_i).
        active_tolerance: the numba backend skips a cell while the bound on how far its
            logits moved since its last update (the globals' change, the coupling's, and gamma
            times its neighbours' largest change of q) stays <= this: its q is then within a
            factor exp(+-2 active_tolerance) of its exact update, concept by concept. Skipping
            never lowers the ELBO (the cell keeps its value); 0 skips only cells whose inputs did
            not change at all (exact).
    """

    anneal_iterations: int = 0
    damping: float = 0.0
    pi_family: PiFamily = "dirichlet"
    tolerance: float = 1e-7
    backend: Literal["auto", "torch", "numba"] = "auto"
    init: Literal["one-hot", "soft"] = "one-hot"
    support: int = 0
    threshold: float = 1e-4
    active_tolerance: float = 1e-3

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ValueError:
            return ValueError(f"VariationalOptions.{name}={getattr(self, name)!r}: {why}")

        if not is_int(self.anneal_iterations) or self.anneal_iterations < 0:
            raise bad("anneal_iterations", "must be an integer >= 0")
        if not (is_number(self.damping) and 0 <= self.damping < 1):
            raise bad("damping", "must lie in [0, 1)")
        if self.pi_family not in ("dirichlet", "stick-breaking"):
            raise bad("pi_family", "must be 'dirichlet' or 'stick-breaking'")
        if not is_finite_number(self.tolerance):
            raise bad("tolerance", "must be a finite number >= 0")
        if self.tolerance < 0:
            raise bad("tolerance", "must be >= 0")
        if self.backend not in ("auto", "torch", "numba"):
            raise bad("backend", "must be 'auto', 'torch' or 'numba'")
        if self.init not in ("one-hot", "soft"):
            raise bad("init", "must be 'one-hot' or 'soft'")
        if not is_int(self.support) or self.support < 0:
            raise bad("support", "must be an integer >= 0 (0: all concepts)")
        if not (is_number(self.threshold) and 0 <= self.threshold < 1):
            raise bad("threshold", "must lie in [0, 1)")
        if not (is_finite_number(self.active_tolerance) and self.active_tolerance >= 0):
            raise bad("active_tolerance", "must be a finite number >= 0")


NUMBA_ONLY = ("support", "threshold", "active_tolerance")
"""The options only the compiled sparse backends read (CAVI's and loopy BP's)."""


def warn_numba_only_options(options: object, method: str) -> None:
    """Warn (logger ``"spcopyro"``) that the torch backend ignores the :data:`NUMBA_ONLY`
    options of ``options`` (a :class:`VariationalOptions` or ``LBPOptions``) set away from their
    defaults: on a machine without numba, or LBP's ``"auto"`` at a large gamma D, they had no
    effect and nothing said so."""
    defaults = type(options)()
    changed = [f"{name}={getattr(options, name)!r}" for name in NUMBA_ONLY
               if getattr(options, name) != getattr(defaults, name)]  # fmt: skip
    if changed:
        logging.getLogger("spcopyro").warning(
            "%s runs on the torch backend, which ignores %s (the numba backend's options)",
            method,
            ", ".join(changed),
        )
