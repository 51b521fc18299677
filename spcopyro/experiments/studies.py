"""Side studies of the issue: how much each modality changes the map, and the sentence setting.

* :func:`modality_ablation`: ARI against the truth of SpCoMapping with the MRF only, + words,
  + images, and both (``SpCoConfig.use_words`` / ``use_images``), over seeds.
* :func:`sentence_study`: the paper's sentence setting (Section 5, Table 5) on a synthetic house
  whose utterances are partly sentences with filler words: the share of concepts whose top word
  is a filler, with plain counts and with tf-idf weighting (eq. 20).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from spcopyro.config import SpCoSettings
from spcopyro.experiments.methods import fit_spco
from spcopyro.metrics import adjusted_rand_index
from spcopyro.synthetic import FILLER_WORDS, HouseSpec, make_house

ABLATIONS = {
    "MRF only": dict(use_words=False, use_images=False),
    "+ words": dict(use_words=True, use_images=False),
    "+ images": dict(use_words=False, use_images=True),
    "words + images": dict(use_words=True, use_images=True),
}


def modality_ablation(
    config: SpCoSettings,
    *,
    sweeps: int,
    seeds: tuple[int, ...] = (0, 1, 2),
    spec: HouseSpec | None = None,
) -> dict[str, list[float]]:
    """ARI against the truth, per setting of :data:`ABLATIONS`, one entry per seed (the synthetic
    house of that seed, the chain of that seed)."""
    scores: dict[str, list[float]] = {name: [] for name in ABLATIONS}
    for seed in seeds:
        house = make_house(seed=seed, spec=spec)
        for name, switches in ABLATIONS.items():
            result, _ = fit_spco(house, config.replace(**switches), sweeps=sweeps, seed=seed)
            scores[name].append(adjusted_rand_index(result.label_image(), house.truth))
    return scores


@dataclass(frozen=True)
class SentenceScores:
    """Per weighting: the share of the concepts in use whose most probable word is a filler,
    and each concept's top words (largest concepts first)."""

    filler_top_share: dict[str, float]
    top_words: dict[str, list[list[str]]]


def sentence_study(
    config: SpCoSettings,
    *,
    sweeps: int,
    seed: int = 0,
    sentence_fraction: float = 0.5,
    min_cells: int = 50,
) -> SentenceScores:
    """Fit a synthetic house with ``sentence_fraction`` of the utterances given as sentences,
    with word counts and with tf-idf (eq. 20); for each concept labelling at least
    ``min_cells`` cells, is its most probable word a filler (:data:`FILLER_WORDS`)?"""
    house = make_house(seed=seed, spec=HouseSpec(sentence_fraction=sentence_fraction))
    share: dict[str, float] = {}
    tops: dict[str, list[list[str]]] = {}
    for weighting in ("count", "tfidf"):
        result, _ = fit_spco(
            house, config.replace(word_weighting=weighting), sweeps=sweeps, seed=seed
        )
        sizes = np.bincount(result.labels, minlength=result.config.num_concepts)
        concepts = [int(c) for c in result.concepts_in_use() if sizes[c] >= min_cells]
        words = [[w for w, _ in result.top_words(c, 3)] for c in concepts]
        tops[weighting] = words
        fillers = [bool(ws) and ws[0] in FILLER_WORDS for ws in words]
        share[weighting] = float(np.mean(fillers)) if fillers else float("nan")
    return SentenceScores(share, tops)


STUDY_CONFIG = dict(preset="original-code", gamma=3.0)
"""The SpCoMapping variant the studies use (the table's row A': regions and sharp words)."""


def write_studies(out, *, sweeps: int, seeds: tuple[int, ...]) -> str:
    """Run both studies with the variant of :data:`STUDY_CONFIG`; write ``studies.md`` and
    ``studies.json`` into ``out`` and return the markdown."""
    import json
    from pathlib import Path

    from spcopyro.config import preset

    config = preset(STUDY_CONFIG["preset"], gamma=STUDY_CONFIG["gamma"])
    ablation = modality_ablation(config, sweeps=sweeps, seeds=seeds)
    sentences = sentence_study(config, sweeps=sweeps, seed=seeds[0])
    lines = [
        "# Side studies",
        "",
        f"SpCoMapping with the `{STUDY_CONFIG['preset']}` values and gamma "
        f"{STUDY_CONFIG['gamma']}, {sweeps} sweeps; synthetic houses of seeds {list(seeds)}.",
        "",
        "## Modality ablation: ARI against the truth",
        "",
        "| setting | " + " | ".join(f"seed {s}" for s in seeds) + " | mean |",
        "|---|" + "---|" * (len(seeds) + 1),
    ]
    for name, scores in ablation.items():
        cells = " | ".join(f"{v:.3f}" for v in scores)
        lines.append(f"| {name} | {cells} | {np.mean(scores):.3f} |")
    lines += [
        "",
        "## Sentences (half the utterances are sentences with filler words)",
        "",
        "| word weighting | share of concepts whose top word is a filler | top words of the "
        "largest concepts |",
        "|---|---|---|",
    ]
    for weighting, share in sentences.filler_top_share.items():
        tops = "; ".join(", ".join(ws) for ws in sentences.top_words[weighting][:4])
        lines.append(f"| {weighting} | {share:.2f} | {tops} |")
    markdown = "\n".join(lines) + "\n"
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "studies.md").write_text(markdown)
    payload = {
        "config": STUDY_CONFIG, "sweeps": sweeps, "seeds": list(seeds), "ablation": ablation,
        "sentences": {"filler_top_share": sentences.filler_top_share,
                      "top_words": sentences.top_words},
    }  # fmt: skip
    (out / "studies.json").write_text(json.dumps(payload, indent=1) + "\n")
    return markdown
