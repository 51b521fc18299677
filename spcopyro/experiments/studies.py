"""Side studies of the issue: how much each modality changes the map, and the sentence setting.

Both run as shipped studies (:mod:`spcopyro.study.side_studies`: ``modality.toml`` and
``sentences.toml``); this module holds their rows and their report (:func:`studies_markdown`):

* the modality ablation: ARI against the truth of SpCoMapping with the MRF only, + words,
  + images, and both (``SpCoConfig.use_words`` / ``use_images``: :data:`ABLATIONS`), over seeds;
* sentences with filler words as in the paper's Section 5 (not its Table 5 setting: 20 fixed
  sentences in a real room) on a synthetic house whose utterances are partly sentences: the
  share of concepts whose top word is a filler, with plain counts and with tf-idf weighting
  (eq. 20): :class:`SentenceScores`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

ABLATIONS = {
    "MRF only": dict(use_words=False, use_images=False),
    "+ words": dict(use_words=True, use_images=False),
    "+ images": dict(use_words=False, use_images=True),
    "words + images": dict(use_words=True, use_images=True),
}


@dataclass(frozen=True)
class SentenceScores:
    """Per weighting: the share of the concepts in use whose most probable word is a filler,
    and each concept's top words (largest concepts first)."""

    filler_top_share: dict[str, float]
    top_words: dict[str, list[list[str]]]


SENTENCES_NOT_TABLE_5 = (
    "Not the paper's Table 5 setting: that is 20 fixed sentences in a real laboratory room "
    '("Here is kitchen", "TV and sofa are in living space", ...), each given 5 times, fitted '
    "with alpha 1e6, beta 0.6, chi 100, gamma 4 (Section 5.1); here the synthetic house's "
    'template sentences ("here is the kitchen", "there is a sofa here", ...) with the values '
    "above, and the score is how often a template's filler word tops a concept."
)
"""How the sentence study differs in kind from the paper's Section 5 (``studies.md``)."""

STUDY_CONFIG = dict(preset="original-code", gamma=3.0)
"""The SpCoMapping variant the studies use (the table's row A': regions and sharp words)."""


def studies_markdown(
    ablation: dict[str, list[float]], sentences: SentenceScores, *, sweeps: int,
    seeds: tuple[int, ...],
) -> str:  # fmt: skip
    """``studies.md``: the modality ablation's ARI per setting and seed, and the sentence
    study's filler share and top words per weighting."""
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
        "## Sentences (half the utterances are sentences with filler words; the house of "
        f"seed {seeds[0]} alone)",
        "",
        SENTENCES_NOT_TABLE_5,
        "",
        "| word weighting | share of concepts whose top word is a filler | top words of the "
        "largest concepts |",
        "|---|---|---|",
    ]
    for weighting, share in sentences.filler_top_share.items():
        tops = "; ".join(", ".join(ws) for ws in sentences.top_words[weighting][:4])
        lines.append(f"| {weighting} | {share:.2f} | {tops} |")
    return "\n".join(lines) + "\n"
