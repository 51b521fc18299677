"""A variational fit of :func:`spcopyro.fit.house.fit_house_chains` saved on Ctrl-C and resumed:
the fit's settings as the checkpoint records them (:mod:`spcopyro.guides.checkpoint`)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from spcopyro.config import SpCoSettings
from spcopyro.fit.gibbs_chains import preparation_record
from spcopyro.fit.starts import Init, init_name
from spcopyro.guides.checkpoint import (
    CheckpointMismatchError,
    load_variational,
    save_variational,
)
from spcopyro.inference.driver import DriveInterrupted
from spcopyro.inference.protocol import (
    InferenceMethod,
    Resumption,
    method_options,
    options_for_start,
    start_filled,
)
from spcopyro.model import ModelData


@dataclass
class VariationalSaving:
    """What a variational fit's checkpoint is made for: the method and its options, the data,
    the settings, and the caller's run (sweeps, seeds, start); checked on resuming."""

    inference: InferenceMethod
    options: object | None
    data: ModelData
    settings: SpCoSettings
    sweeps: int
    seeds: Sequence[int]
    init: Init

    def _given_options(self) -> object:
        """The options as given (None: the method's defaults)."""
        kind = self.inference.options_type
        return method_options(self.options, kind, self.inference.title or self.inference.name)

    def _options(self) -> object:
        """The options as the fit runs them: fields left to the start (svi's None) set to what
        it gets (:func:`~spcopyro.inference.protocol.options_for_start`; given start labels
        unless ``init`` is random), so a checkpoint records what ran and is compared with it
        (``anneal_iterations``: None against 100)."""
        given = init_name(self.init) != "random"
        return options_for_start(self._given_options(), given_start=given)

    def _record(self) -> dict[str, object]:
        return {"method": self.inference.name, "sweeps": int(self.sweeps),
                "seeds": [int(s) for s in self.seeds], "init": init_name(self.init),
                "data_preparation": preparation_record(self.settings)}  # fmt: skip

    def save(self, path: str | os.PathLike[str], stop: DriveInterrupted) -> Path | None:
        """Save the q(C) and record ``stop`` carries into ``path``; None (nothing written) when
        it carries no q(C) or no iteration was completed."""
        if stop.marginals is None or not len(stop.trajectory.objective):
            return None
        return save_variational(
            path, stop.marginals, stop.trajectory, method=self.inference.name,
            options=self._options(), config=self.settings.model, data=self.data,
            record=self._record(),
        )  # fmt: skip

    def load(self, path: str | os.PathLike[str]) -> Resumption:
        """The q(C) and record saved in ``path``
        (:class:`~spcopyro.guides.checkpoint.CheckpointMismatchError`, a ValueError, naming what
        differs if it was made for another fit; one naming an option left unset says so)."""
        try:
            return load_variational(
                path, self.data, self.settings.model, method=self.inference.name,
                options=self._options(), record=self._record(),
            )  # fmt: skip
        except CheckpointMismatchError as error:
            filled = start_filled(self._given_options(), self._options())  # left to the start
            unset = [name for name in filled if name in error.options]
            if not unset:
                raise
            raise CheckpointMismatchError(  # e.g. svi's anneal_iterations: 100 for every start
                error.path, error.problems, error.options,
                note=f"{', '.join(unset)} unset: the start's default, 'here' above, which changed "
                "on 2026-12-05; to resume, set the checkpoint's value in options= (fit's "
                "--method-option NAME=VALUE)",
            ) from None  # fmt: skip
