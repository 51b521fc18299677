"""The experiment's side studies (``spcopyro experiment --studies``) as shipped studies (issue 26):
the modality ablation (``modality.toml``) and the sentence study (``sentences.toml``).

:func:`side_studies` sets their budgets as the command does (the sweeps, the modality seeds;
the sentence house is the first seed's); :func:`write_studies` runs them with the study engine
into ``OUT/studies/modality`` and ``OUT/studies/sentences`` (each cached and resumable, with
its own ``results.csv`` and ``report.md``) and writes ``studies.md`` and ``studies.json`` from
their tables alone (:func:`spcopyro.experiments.studies.studies_markdown`).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path

from spcopyro._util.outputs import replace_text
from spcopyro.experiments.studies import STUDY_CONFIG, SentenceScores, studies_markdown
from spcopyro.study import STUDIES
from spcopyro.study.report import with_warnings
from spcopyro.study.run import run_study
from spcopyro.study.spec import Study, load_study
from spcopyro.study.table import TABLE, read_table

__all__ = ["MODALITY", "SENTENCES", "side_studies", "write_studies"]

MODALITY = STUDIES / "modality.toml"
"""The modality ablation: (A') with the MRF only, + words, + images, both."""
SENTENCES = STUDIES / "sentences.toml"
"""The sentence study: plain counts against tf-idf on a house with filler words."""


def side_studies(*, sweeps: int, seeds: Sequence[int]) -> tuple[Study, Study]:
    """The modality and sentence studies with ``sweeps`` a fit, the modality ablation on the
    houses of ``seeds`` and the sentence study on the first one's."""
    if not seeds:
        raise ValueError("seeds must name at least one synthetic house")
    modality, sentences = load_study(MODALITY), load_study(SENTENCES)
    budget = (("*", int(sweeps)),)
    return (
        dataclasses.replace(modality, sweeps=budget, seeds=tuple(seeds)),
        dataclasses.replace(sentences, sweeps=budget, seeds=(int(seeds[0]),)),
    )


def _ok(rows: list[dict[str, object]], variant: str) -> list[dict[str, object]]:
    return [r for r in rows if r["variant"] == variant and r["status"] == "ok"]


def write_studies(
    out: str | os.PathLike[str],
    *,
    sweeps: int,
    seeds: Sequence[int],
    workers: int = 1,
    rerun_stale: bool = False,
    report: Callable[[str], None] = lambda message: None,
) -> str:
    """Run both side studies (:func:`side_studies`) into ``out/studies/``; write
    ``studies.md`` and ``studies.json`` into ``out`` from their tables and return the
    markdown. A failed cell is left out of them (and listed in its study's ``report.md``)."""
    out = Path(out)
    modality, sentences = side_studies(sweeps=sweeps, seeds=seeds)
    tables = {}
    for study in (modality, sentences):
        folder = out / "studies" / study.name
        run_study(study, folder, workers=workers, rerun_stale=rerun_stale, report=report)
        tables[study.name] = read_table(folder / TABLE)
    ablation = {
        v.name: [float(r["ari"]) for r in _ok(tables[modality.name], v.name)]  # type: ignore[arg-type]
        for v in modality.variants
    }
    share: dict[str, float] = {}
    tops: dict[str, list[list[str]]] = {}
    for variant in sentences.variants:
        for row in _ok(tables[sentences.name], variant.name):
            value = row["filler_top_share"]
            share[variant.name] = math.nan if value is None else float(value)  # type: ignore[arg-type]
            tops[variant.name] = json.loads(str(row["concept_words"]))
    scores = SentenceScores(share, tops)
    markdown = studies_markdown(ablation, scores, sweeps=sweeps, seeds=tuple(seeds))
    for study in (modality, sentences):  # the cells' warnings, as each study's report.md
        markdown = with_warnings(markdown, tables[study.name],
                                 f"studies/{study.name}/{TABLE}",
                                 f"Cells with warnings: {study.name}")  # fmt: skip
    out.mkdir(parents=True, exist_ok=True)
    replace_text(out / "studies.md", markdown)  # each whole or not at all
    payload = {
        "config": STUDY_CONFIG, "sweeps": sweeps, "seeds": list(seeds), "ablation": ablation,
        "sentences": {"filler_top_share": share, "top_words": tops},
    }  # fmt: skip
    replace_text(out / "studies.json", json.dumps(payload, indent=1) + "\n")
    return markdown
