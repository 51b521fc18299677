"""``where``: other words answered by the same concept (one concept may hold two rooms), and the
per-cell probability's mass on concepts absent from the map, on hand-made results."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hand_results import two_rooms

from spcopyro.cli.main import main
from spcopyro.results.concept_names import answered_words
from spcopyro.results.concept_words import ranked as ranked_keys
from spcopyro.results.uncertainty import unmapped_mass, unmapped_note, where_probability
from spcopyro.results.where import (
    SHARED_ANSWER_P,
    answers_by_concept,
    shared_answer_note,
    shared_answers,
)


def test_a_concept_answering_two_words_lists_the_other():
    # area prior: sizes 150, 149, 1; 'bed': 0.2*150, 0.6*149, 0.15*1 -> concept 1 at 0.748;
    # 'sofa': 0.2*150, 0.3*149, 0.15*1 -> concept 1 at 44.7 / 74.85 = 0.597 (> 0.5)
    result = two_rooms()
    bed = result.where("bed")
    assert bed.concept == 1
    assert [w for w, _ in bed.shared_with] == ["sofa"]
    assert bed.shared_with[0][1] == pytest.approx(44.7 / 74.85)
    sofa = result.where("sofa")
    assert sofa.concept == 1 and [w for w, _ in sofa.shared_with] == ["bed"]
    kitchen = result.where("kitchen")  # concept 0 answers no other word
    assert kitchen.concept == 0 and kitchen.shared_with == ()
    note = shared_answer_note(bed)
    assert (
        note is not None
        and "concept 1 is also the answer, at p(concept | word) > 0.5, for 'sofa' (0.60)" in note
    )
    assert shared_answer_note(kitchen) is None


def test_shared_answers_keeps_only_words_above_the_threshold_and_names_a_few():
    w = np.array([[0.5, 0.3, 0.2, 0.25, 0.25], [0.1, 0.2, 0.3, 0.2, 0.2]])  # [L, V]
    prior = np.array([0.5, 0.5])
    words = ("a", "b", "c", "d", "e")
    # p(0 | word): a 0.833, b 0.6, c 0.4 (answered by concept 1), d 0.556, e 0.556
    shared = shared_answers(w, prior, 0, words, "a")
    assert [word for word, _ in shared] == ["b", "d", "e"]
    assert shared_answers(w, prior, 0, words, "a", threshold=0.58) == (("b", pytest.approx(0.6)),)
    assert SHARED_ANSWER_P == 0.5
    more = (("f", 0.51), ("g", 0.505))
    answer = dataclasses.replace(two_rooms().where("kitchen"), shared_with=shared + more)
    note = shared_answer_note(answer, shown=3)
    assert (
        note is not None
        and note.count(" (0.") == 3
        and "(p " not in note
        and "and 2 more words:" in note
    )


def test_one_word_over_the_few_shown_is_named_not_counted():
    """room1dk6's default fit (0.75 m footprint, seed 0): `where OUT bedroom`'s note read
    "for 'bed' (0.97), 'shelf' (0.76), 'living' (0.73) and 1 more word", hiding 'table' behind
    a phrase as long as its name. One word over the three shown is now named."""
    shared = (("bed", 0.97), ("shelf", 0.76), ("living", 0.73), ("table", 0.57))
    answer = dataclasses.replace(two_rooms().where("kitchen"), shared_with=shared)
    note = shared_answer_note(answer, shown=3)
    assert note is not None and "more word" not in note
    assert "for 'bed' (0.97), 'shelf' (0.76), 'living' (0.73), 'table' (0.57): if one" in note


def test_the_note_shows_a_p_just_above_the_threshold_above_it():
    """room1ldk5's LBP fit: 'kitchen's note named 'chair' "(0.50)" at p(concept | word) =
    0.5003, under its "> 0.5". The value now takes the digits that show it above 0.5."""
    answer = dataclasses.replace(
        two_rooms().where("kitchen"), shared_with=(("chair", 0.5003), ("sofa", 0.81))
    )
    note = shared_answer_note(answer)
    assert note is not None and "> 0.5, for 'chair' (0.5003), 'sofa' (0.81):" in note


@pytest.mark.parametrize("heard_only", [False, True])
def test_answered_words_reads_each_words_argmax(heard_only):
    """``answered_words`` takes each word's answer (argmax, first of ties) and ranks a concept's
    answered words by its row of the word table: the same words, in the same order, as ranking
    :func:`answers_by_concept`'s (sorted by p(C | word)) again, which it did. Tied columns of
    p(C | word), words heard off the map (total 0) and a concept with nothing heard included."""
    from types import SimpleNamespace

    rng = np.random.default_rng(3)
    posterior = rng.dirichlet(np.ones(4), size=12).T  # [L=4, V=12]
    posterior[:, 5] = posterior[:, 2]  # a tie between words
    posterior[:, 7] = 0.25  # a tie between concepts: the first
    w = rng.dirichlet(np.ones(12), size=4)  # [L, V]
    w[1, 3] = w[1, 9]  # a tie in the table
    totals = np.where(np.arange(12) % 5 == 4, 0.0, 1.0)  # [V] words 4 and 9 heard off the map
    vocabulary = tuple(f"w{v}" for v in range(12))
    result = SimpleNamespace(
        emissions=(SimpleNamespace(name="words", probabilities=w),),
        vocabulary=vocabulary,
        word_posteriors=lambda: posterior,
        word_totals=totals,
        heard=lambda c: 0 if c == 3 else 1,
    )
    expected = {}
    for c, answered in answers_by_concept(posterior).items():  # the former definition
        if heard_only and c == 3:
            continue
        columns = np.array(sorted(v for v, _ in answered if not (heard_only and totals[v] == 0)),
                           dtype=np.int64)  # fmt: skip
        if columns.size:
            expected[c] = tuple(vocabulary[v] for v in columns[ranked_keys(w[c, columns])])
    assert len(expected) >= 2
    assert answered_words(result, heard_only=heard_only) == expected


def test_answers_by_concept_ranks_each_concepts_words_as_both_callers_read_them():
    """One ranking of each concept's answered words serves ``where``'s shared answers (exact p);
    the words that may name a concept are the same (``answered_words``, which orders them by
    p(word | concept), rounded to RANK_DECIMALS: a near-tie in vocabulary order)."""
    posterior = np.array([[0.6, 0.60000001, 0.3, 0.5], [0.4, 0.39999999, 0.7, 0.5]])  # [L, V]
    assert answers_by_concept(posterior) == {0: [(1, 0.60000001), (0, 0.6), (3, 0.5)],
                                             1: [(2, 0.7)]}  # fmt: skip  # 3: first of ties
    assert answers_by_concept(np.zeros((2, 0))) == {}
    result = two_rooms()
    ranked = answers_by_concept(result.word_posteriors())
    named = {c: {result.vocabulary[v] for v, _ in vs} for c, vs in ranked.items()}
    assert {c: set(words) for c, words in answered_words(result).items()} == named
    words = result.emission("words")  # bed and sofa said alike in concept 1, to the last bits
    w = np.array(words.probabilities)  # [L, V] kitchen, bed, sofa
    w[1] = [0.1, 0.45, 0.45 + 1e-15]
    tied = dataclasses.replace(
        result, emissions=(*result.emissions[:-1], dataclasses.replace(words, probabilities=w))
    )
    assert answered_words(tied)[1] == ("bed", "sofa")  # not sofa first by 1e-15
    w, prior = result.w, result.concept_prior("area")
    exact = answers_by_concept(result.word_posteriors())[1]
    assert shared_answers(w, prior, 1, result.vocabulary, "") == tuple(
        (result.vocabulary[v], p) for v, p in exact if p > SHARED_ANSWER_P
    )


def unmapped_result():
    """two_rooms without its speck (its cell joins the right room), with marginals in which
    cell 0 of the right room holds 0.4 on concept 2, which labels no cell of the map."""
    base = two_rooms()
    labels = np.where(base.labels == 2, 1, base.labels)  # [N]
    marginals = np.eye(3)[labels]  # [N, 3]
    right = int(np.flatnonzero(labels == 1)[0])
    marginals[right] = [0.0, 0.6, 0.4]
    return dataclasses.replace(base, labels=labels, marginals=marginals), right


def test_where_probability_counts_the_maps_concepts_and_says_what_it_leaves_out():
    result, cell = unmapped_result()
    # area prior, sizes 150 / 150: p(1 | bed) = 0.6 * 150 / (0.2 * 150 + 0.6 * 150) = 0.75
    probability = where_probability(result, "bed")
    assert probability[cell] == pytest.approx(0.6 * 0.75)  # concept 2's 0.4 not counted
    assert probability[cell + 1] == pytest.approx(0.75)
    mass = unmapped_mass(result)
    assert mass is not None and mass[cell] == pytest.approx(0.4)
    assert mass.sum() == pytest.approx(0.4)
    note = unmapped_note(result)
    assert note == (
        f"not counted: {0.4 / 300:.1%} of a cell's probability on average, up to 40%, "
        "lies on concepts absent from the map"
    )
    assert unmapped_note(two_rooms()) is None  # a point estimate: nothing left out
    assert unmapped_note(dataclasses.replace(result, marginals=np.eye(3)[result.labels])) is None


def test_where_prints_the_shared_concept_and_the_unmapped_mass(tmp_path, capsys):
    result, _ = unmapped_result()
    out = result.save(tmp_path / "fit")
    assert main(["where", str(out), "bed", "--out", str(tmp_path / "bed.png")]) == 0
    printed = capsys.readouterr().out
    assert "note: concept 1 is also the answer, at p(concept | word) > 0.5, for 'sofa'" in printed
    assert "lies on concepts absent from the map)" in printed
    assert (tmp_path / "bed_probability.png").is_file()
    assert main(["where", str(out), "kitchen"]) == 0
    printed = capsys.readouterr().out
    assert "also the answer" not in printed


def test_where_names_what_its_probabilities_are(tmp_path, capsys):
    """where's threshold line and its probability figure said "marginals" of every fit: a CAVI
    fit's q(C) and a Gibbs fit's label frequencies over 50 kept samples (steps of 1/50) read
    alike. Each now names its source."""
    from spcopyro.results.uncertainty import marginals_source

    result, _ = unmapped_result()
    sampled = dataclasses.replace(result, inference={"marginal_samples": 50})
    assert marginals_source(sampled) == "Gibbs label frequencies over 50 kept samples"
    vi_gibbs = dataclasses.replace(sampled, method="vi-gibbs")
    assert marginals_source(vi_gibbs) == "Gibbs label frequencies over 50 kept samples (vi-gibbs)"
    cavi = dataclasses.replace(result, method="cavi")
    assert marginals_source(cavi) == "q(C) of cavi"
    assert marginals_source(two_rooms()) == "point estimate"  # no marginals
    for fit, source in [(cavi, "q(C) of cavi"),
                        (sampled, "Gibbs label frequencies over 50 kept samples")]:  # fmt: skip
        out = fit.save(tmp_path / fit.method)
        assert main(["where", str(out), "bed", "--out", str(tmp_path / f"{fit.method}.png")]) == 0
        assert f" ({source}; not counted:" in capsys.readouterr().out


def test_the_where_figure_names_its_probabilities_as_the_line_does():
    """where's figure title said "per-cell probability from the marginals" of every fit while
    the printed line and the probability figure said "Gibbs label frequencies over 50 kept
    samples" (or "q(C) of cavi") of the same numbers: the title now says it in their words."""
    from spcopyro.figures.plotting import where_figure

    result, _ = unmapped_result()
    sampled = dataclasses.replace(result, inference={"marginal_samples": 50})
    cavi = dataclasses.replace(result, method="cavi")
    for fit, source in [(sampled, "per-cell probability: Gibbs label frequencies over 50 kept "
                         "samples"), (cavi, "per-cell probability: q(C) of cavi"),
                        (two_rooms(), "point estimate")]:  # fmt: skip
        (ax,) = [a for a in where_figure(fit, fit.where("bed")).axes if a.get_title()]
        assert f" prior; {source})\n" in ax.get_title(), ax.get_title()
        assert "marginals" not in ax.get_title()


def test_navigate_says_the_unmapped_mass_as_where_does(tmp_path, capsys):
    """navigate's goals are chosen by where's probability, which counts the map's concepts only:
    where says what it leaves out (unmapped_note), and navigate says it the same way, once."""
    result, _ = unmapped_result()
    out = result.save(tmp_path / "fit")
    argv = ["navigate", str(out), "go to the bed", "--start=2.5,0.3", "--radius", "0.05"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert printed.count(f"note: {unmapped_note(result)}\n") == 1
    plain = two_rooms().save(tmp_path / "plain")  # a point estimate: nothing left out
    assert main(["navigate", str(plain), *argv[2:]]) == 0
    assert "not counted" not in capsys.readouterr().out
