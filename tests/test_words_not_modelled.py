"""A fit that did not model its words (``use_words`` off) lists no words for its concepts.

Its w is the prior's (the posterior mean of no counts: uniform), every word tied, so a list of
"top words" is the vocabulary in tie order: the embedded house's five concepts all read
"restroom 0.06, paper 0.06, toilet 0.06" in concepts.json, and each line of the listing, the
legend and the map's labels named the words heard there at the prior's 0.06, as if the concept
meant them. The listing's first line, the legend's title and ``where`` now say once that the
words were not modelled, no concept lists any, and ``where`` warns that its answer is the
prior's whatever the word.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
from hand_results import WORDS, two_rooms

from spcopyro.cli.concept_listing import next_step, print_concepts
from spcopyro.config import preset
from spcopyro.figures.map_pieces import concept_handles, region_text
from spcopyro.figures.plotting import semantic_map_figure, where_figure
from spcopyro.fit.house import fit_house
from spcopyro.results.concept_names import concept_names
from spcopyro.results.concept_words import shown_top_words
from spcopyro.results.result import EmissionTable, SpCoResult
from spcopyro.synthetic import make_house

WORDS_NOT_MODELLED = "not modelled (use_words off)"
NOT_MODELLED_WARNING = "this fit did not model its words (use_words off)"


def _rooms(use_words: bool) -> SpCoResult:
    """The two rooms with 'kitchen' heard 4 times on the left, 'bed' 3 and 'sofa' 2 on the
    right, nothing at the speck (concept 2); their posterior means under ``use_words`` (beta
    1), or the prior's uniform rows without it, as a fit computes them."""
    base = two_rooms()
    counts = np.array([[4.0, 0.0, 0.0], [0.0, 3.0, 2.0], [0.0, 0.0, 0.0]])  # [L, V]
    w = (counts + 1.0) / (counts.sum(1, keepdims=True) + 3.0)  # [L, V]
    if not use_words:
        w = np.full_like(w, 1.0 / 3.0)  # no counts in the statistics: the prior's mean
    totals = np.array([[3.0, 3.0, 4.0], [2.0, 2.0, 5.0], [0.0, 0.0, 0.0]])  # [L, 1 + M]
    return dataclasses.replace(
        base,
        config=base.config.replace(use_words=use_words),
        emissions=(base.emissions[0], EmissionTable("words", WORDS, w)),
        concept_totals=totals,
        word_counts=counts,
        inference={"parameters": "posterior mean given the point labels"},
    )


def _texts(figure) -> list[str]:
    return [t.get_text() for t in figure.findobj(lambda a: hasattr(a, "get_text"))]


def test_the_listing_says_once_that_words_were_not_modelled(capsys):
    modelled, unmodelled = _rooms(True), _rooms(False)
    print_concepts(modelled)
    assert "kitchen 0.71" in capsys.readouterr().out  # the same house, its words modelled
    print_concepts(unmodelled)
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"concepts (words: {WORDS_NOT_MODELLED}):", lines
    left, right = lines[1:3]
    assert left == "  concept   0:    150 cells    4 words", left
    assert right == "  concept   1:    149 cells    5 words", right
    assert not any(word in line for line in lines for word in WORDS), lines
    assert not any("distinctive" in line for line in lines), lines  # no lifts to speak of
    assert shown_top_words(unmodelled, 0, 3) == []


def test_the_map_labels_and_legend_list_no_words():
    modelled, unmodelled = _rooms(True), _rooms(False)
    assert region_text(modelled, 0).splitlines()[1] == "kitchen 0.71 x1.7"
    assert region_text(unmodelled, 0) == "[0]"
    assert region_text(unmodelled, 1, largest=False) == "[1]"  # its name is a tied word
    assert region_text(unmodelled, 2) == "[2]\nno words heard here"  # data, as before
    labels = [h.get_label() for h in concept_handles(unmodelled, np.zeros((3, 3), np.uint8))]
    assert labels[:2] == ["[0] 150 cells, 4 words heard", "[1] 149 cells, 5 words heard"]
    figure = semantic_map_figure(unmodelled)
    title = figure.axes[0].get_legend().get_title().get_text()
    assert title == f"concepts, largest first: words {WORDS_NOT_MODELLED}", title
    texts = _texts(figure)
    assert not any(word in text for text in texts for word in WORDS), texts


def test_where_warns_that_the_answer_is_the_prior():
    modelled, unmodelled = _rooms(True), _rooms(False)
    assert not any(NOT_MODELLED_WARNING in w for w in modelled.where("kitchen").warnings)
    answer = unmodelled.where("kitchen")
    assert answer.warnings[0].startswith(NOT_MODELLED_WARNING), answer.warnings
    assert "says nothing about where 'kitchen' is" in answer.warnings[0]
    figure = where_figure(unmodelled, answer)
    assert f"its words: {WORDS_NOT_MODELLED}" in figure.axes[0].get_title()


def test_a_fit_without_words_lists_none_and_where_says_why(tmp_path, capsys):
    """Through the library, the files and the command: ``fit``'s listing, its last line (no
    ``where`` to suggest) and ``where``."""
    from spcopyro.cli.main import main

    settings = preset("original-code", cell_size=None, use_words=False, num_concepts=6)
    result = fit_house(make_house(seed=0), settings, sweeps=5, progress=False)
    out = result.save(tmp_path / "fit")
    print_concepts(result)
    listing = capsys.readouterr().out.splitlines()
    assert listing[0] == f"concepts (words: {WORDS_NOT_MODELLED}):", listing
    assert not any(word in line for line in listing[1:] for word in result.vocabulary), listing
    step = next_step(result, result.concepts(), out)
    assert step == f"next: open {out / 'semantic_map.png'}", step
    assert main(["where", str(out), "kitchen"]) == 0
    printed = capsys.readouterr()
    assert f"its words: {WORDS_NOT_MODELLED})" in printed.out.splitlines()[0], printed.out
    assert f"warning: {NOT_MODELLED_WARNING}" in printed.err.splitlines()[0], printed.err


def test_concepts_json_and_the_names_hold_no_tied_words(tmp_path):
    """``concepts.json`` said ``"top_words": [["kitchen", 0.33], ["bed", 0.33], ...]`` and named
    every concept "kitchen" (a word in tie order); it keeps its keys, with empty word lists and
    a ``words_note``, as for a concept where no word was heard, and names the concepts
    ``concept N``. The saved result loads and answers ``where`` as before."""
    from spcopyro.robot.navigation.places import place_graph

    unmodelled = _rooms(False)
    assert concept_names(unmodelled) == {0: "concept 0", 1: "concept 1", 2: "concept 2"}
    assert concept_names(_rooms(True))[0] == "kitchen"
    unmodelled.save(tmp_path / "fit")
    saved = json.loads((tmp_path / "fit" / "concepts.json").read_text())
    by_id = {c["concept"]: c for c in saved}
    for c in (0, 1):
        assert by_id[c]["top_words"] == [] and by_id[c]["distinctive_words"] == []
        assert by_id[c]["words_note"] == f"words {WORDS_NOT_MODELLED}"
        assert by_id[c]["words_heard"] > 0
    assert by_id[2]["words_note"] == "no words heard here"
    loaded = SpCoResult.load(tmp_path / "fit")
    assert loaded.where("bed").concept == unmodelled.where("bed").concept
    assert loaded.where("bed").warnings[0].startswith(NOT_MODELLED_WARNING), loaded.where("bed")
    places = place_graph(unmodelled, min_area=0.0).places
    assert all(p.words == () and p.name == f"concept {p.concept}" for p in places), places


def test_no_distinctive_words_where_the_words_were_not_modelled():
    """A fit without words whose w is not uniform (a w from elsewhere: a fit's rows are the
    prior's, but nothing in the result says so) gave its concepts distinctive words from it:
    ``concepts()`` and the legend said "distinctive: kitchen x1.8" beside no word list. Its
    lifts are no more learnt than its top words: none are listed."""
    modelled = _rooms(True)
    unmodelled = dataclasses.replace(_rooms(False), emissions=modelled.emissions)  # w not uniform
    assert modelled.distinctive_words(0)[0][0] == "kitchen"  # the same w, its words modelled
    assert unmodelled.distinctive_words(0) == []
    assert all(c["distinctive_words"] == [] for c in unmodelled.concepts())
    labels = [h.get_label() for h in concept_handles(unmodelled, np.zeros((3, 3), np.uint8))]
    assert not any("distinctive" in label for label in labels), labels
    assert labels[:2] == ["[0] 150 cells, 4 words heard", "[1] 149 cells, 5 words heard"]
    texts = _texts(semantic_map_figure(unmodelled))
    assert not any(word in text for text in texts for word in WORDS), texts
