"""The concepts ``fit`` prints: the largest with their words, the specks on one line."""

from __future__ import annotations

import shlex
from pathlib import Path
from typing import TYPE_CHECKING

from spcopyro.results.concept_words import (
    ESTIMATED_WORDS,
    MIN_LIFT,
    WORDS_NOT_MODELLED,
    cells_range,
    format_concept_words,
    format_words_heard,
    shown_top_words,
    speck_line,
    words_modelled,
)
from spcopyro.results.specks import speck_concepts, support_text

if TYPE_CHECKING:
    from spcopyro.results.result import SpCoResult

__all__ = ["next_step", "print_concepts"]


def print_concepts(
    result: SpCoResult, limit: int = 10, concepts: list[dict[str, object]] | None = None
) -> None:
    """The ``limit`` largest concepts, one line each: cells, words heard there, the top words
    (posterior means) and the distinctive ones with their lifts
    (:mod:`spcopyro.results.concept_words`), or that no word was heard there. Specks (concepts
    under :data:`~spcopyro.results.concept_words.SPECK_SHARE` of the free cells and
    :data:`~spcopyro.results.concept_words.SPECK_AREA` square metres where fewer
    than :data:`~spcopyro.results.concept_words.SPECK_WORDS` words were heard,
    :func:`~spcopyro.results.concept_words.is_speck`: a doorway or corner cell the Potts field
    holds weakly, docs/real_houses.md) share one line at the end, with how
    much of the posterior holds them (:func:`~spcopyro.results.specks.support_text`).
    ``concepts``: ``result.concepts()`` where the caller has it already (computed if None).
    A fit that did not model its words (:func:`~spcopyro.results.concept_words.words_modelled`)
    says so once, in the first line, and lists no concept's words: each w_l is the prior's."""
    modelled = words_modelled(result)
    parameters = result.inference.get("parameters", ESTIMATED_WORDS)
    if modelled:
        print(f"concepts (words: {parameters}; distinctive: lift = p(word | concept) / p(word) > "
              f"{MIN_LIFT:g}, p(word) the area-weighted mix):")  # fmt: skip
    else:
        print(f"concepts (words: {WORDS_NOT_MODELLED}):")
    further = [t.name for t in result.emissions if t.name not in ("images", "words")]
    concepts = result.concepts() if concepts is None else concepts
    heard_counts = [c["words_heard"] for c in concepts if c["words_heard"] is not None]
    if any(round(h, 1) != round(h) for h in heard_counts):
        print("  (N words: the utterances heard in the concept's cells; the observation "
              "footprint spreads each over the cells around it, so N may be "
              "fractional)")  # fmt: skip
    speck_ids = set(speck_concepts(result))
    specks = [c for c in concepts if c["concept"] in speck_ids]
    listed = [c for c in concepts if c["concept"] not in speck_ids]
    for concept in listed[:limit]:
        heard = concept["words_heard"]
        words = format_concept_words(  # none where the words were not modelled: said above
            shown_top_words(result, concept["concept"], len(concept["top_words"])),
            [(w, r, p) for w, r, p in concept["distinctive_words"]],
            heard,
        )
        for name in further:
            top = concept[f"top_{name}"][:2]
            items = f"{name}: " + ", ".join(f"{item} ({p:.2f})" for item, p in top)
            words = f"{words}; {items}" if words else items
        heard_text = None if heard is None else format_words_heard(heard)
        count = "" if heard is None else f"{heard_text:>4} {_noun(heard_text == '1', 'word')}  "
        cells = f"{concept['cells']:>6} {_noun(concept['cells'] == 1, 'cell')}"
        print(f"  concept {concept['concept']:>3}: {cells} {count}{words}".rstrip())
    summaries = []  # (largest concept, line): the two summary lines, larger concepts first
    if len(listed) > limit:
        rest = [int(c["cells"]) for c in listed[limit:]]
        summaries.append((max(rest), f"  ... {len(rest)} smaller concepts of "
                          f"{cells_range(rest)} in concepts.json"))  # fmt: skip
    if specks:
        sizes, ids = [int(c["cells"]) for c in specks], [int(c["concept"]) for c in specks]
        support = support_text(result, ids)
        support = "" if support is None else f": {support}"
        summaries.append((max(sizes), f"  + {speck_line(ids, sizes)}{support}"))
    for _, line in sorted(summaries, key=lambda s: -s[0]):  # stable: equal sizes keep order
        print(line)
    if not modelled:  # no word lists, no lifts to speak of
        return
    if len(concepts) == 1:  # p(word) is then the concept's own: every lift is 1
        print("  one concept in use: no word can be distinctive (a lift compares concepts)")
    elif not any(c["distinctive_words"] for c in concepts):
        print(f"  no concept has a distinctive word (every lift <= {MIN_LIFT:g})")


def next_step(
    result: SpCoResult, concepts: list[dict[str, object]], out: Path, figures: bool = True
) -> str | None:
    """The line ``fit`` ends with: the figure to open (``figures``), and the ``where`` command
    that asks the map for the place of a word: the first distinctive (else top) word of the
    largest concept, "bathroom" on the default house (``concepts``: ``result.concepts()``, as
    :func:`print_concepts` listed them). None: no figure, and no concept heard a word (or the
    fit did not model its words: ``where`` would answer with the prior, whatever the word)."""
    steps = [f"open {out / 'semantic_map.png'}"] if figures else []
    speck_ids = set(speck_concepts(result))
    for concept in concepts:  # none lists a word where the fit did not model its words
        words = concept["distinctive_words"] or concept["top_words"]
        if words and concept["concept"] not in speck_ids:
            word = str(words[0][0])
            command = ["spcopyro", "where", str(out), word, "--out", f"{out}_{word}.png"]
            steps.append(f"ask where the {word} is (or any word heard, concepts.json): "
                         f"{shlex.join(command)}")  # fmt: skip
            break
    return f"next: {'; '.join(steps)}" if steps else None


def _noun(one: bool, noun: str) -> str:
    """``noun`` for one, else its plural, padded to the plural's width (the columns align)."""
    return f"{noun} " if one else f"{noun}s"
