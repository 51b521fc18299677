"""Speck concepts (a few cells, no words heard) are counted and shown as specks with the share
of the posterior that holds them, not as places: the README's fit printed "10 concepts in use"
over a house of six rooms and four one-cell specks, and said nothing of how weakly the samples
held the specks (their cells took them in 28-56% of the kept samples)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from spcopyro.config import SpCoConfig
from spcopyro.maps import FREE, OccupancyGrid
from spcopyro.results.concept_words import is_speck
from spcopyro.results.result import EmissionTable, SpCoResult, Trace


def _rooms_and_specks(
    agreement: bool = True, marginals: bool = False, specks: int = 2
) -> SpCoResult:
    """Two rooms of 300 cells (words heard in both) and ``specks`` one-cell specks (none heard),
    on a 1 x (600 + specks) map; the kept samples' agreement is 1.0 in the rooms, 0.3 and 0.5 at
    the first two specks, 0.4 at any further one."""
    sizes = [300, 300] + [1] * specks
    n, num = sum(sizes), len(sizes)
    labels = np.repeat(np.arange(num), sizes)  # [N]
    totals = np.zeros((num, 3))  # [L, 1 + M]: cells observed, images, words heard
    totals[:2] = [10.0, 10.0, 5.0]
    agree = np.ones(n)  # [N]
    agree[labels >= 2] = 0.4
    agree[labels == 2], agree[labels == 3] = 0.3, 0.5
    probabilities = np.zeros((n, num), dtype=np.float32)  # [N, L]
    probabilities[np.arange(n), labels] = agree
    probabilities[labels >= 2, 0] = 1.0 - agree[labels >= 2]
    return SpCoResult(
        grid=OccupancyGrid(np.full((1, n), FREE, dtype=np.int8), 0.1, (0.0, 0.0, 0.0)),
        config=SpCoConfig(num_concepts=num, prior="dirichlet"),
        labels=labels,
        pi=np.full(num, 1 / num),
        emissions=(
            EmissionTable("images", ("0", "1"), np.full((num, 2), 0.5)),
            EmissionTable("words", ("a", "b"), np.full((num, 2), 0.5)),
        ),
        trace=Trace(objective=np.zeros(1), num_concepts=np.array([num]), seconds=np.zeros(1)),
        best_iteration=0,
        marginals=probabilities if marginals else None,
        agreement=agree if agreement else None,
        inference={"marginal_samples": 50},
        concept_totals=totals,
    )


def test_the_count_of_concepts_in_use_says_how_many_are_specks():
    from spcopyro.results.specks import in_use_text, speck_concepts

    result = _rooms_and_specks()
    assert speck_concepts(result) == [2, 3]
    assert in_use_text(result) == "4 concepts in use (2 of them specks)"


@pytest.mark.parametrize("source", ["agreement", "marginals"])
def test_the_speck_line_gives_the_posterior_share_that_holds_them(capsys, source):
    from spcopyro.cli.concept_listing import print_concepts

    result = _rooms_and_specks(agreement=source == "agreement", marginals=source == "marginals")
    print_concepts(result)
    (line,) = [s for s in capsys.readouterr().out.splitlines() if s.startswith("  + ")]
    where = "agreement.npy" if source == "agreement" else "the marginals"
    assert line.endswith(
        f": their cells took them in 30-50% of the 50 kept samples ({where}), "
        "the other concepts' cells 100%"
    ), line


def test_a_result_without_per_cell_probabilities_lists_its_specks_without_a_share(capsys):
    from spcopyro.cli.concept_listing import print_concepts

    print_concepts(_rooms_and_specks(agreement=False))
    (line,) = [s for s in capsys.readouterr().out.splitlines() if s.startswith("  + ")]
    assert line.endswith("(concepts 2, 3; concepts.json lists them)"), line


def test_the_semantic_map_counts_and_describes_the_specks():
    import matplotlib.pyplot as plt

    from spcopyro.figures.plotting import semantic_map_figure

    fig = semantic_map_figure(_rooms_and_specks())
    try:
        title = fig.axes[0].get_title()
        assert "4 concepts in use (2 of them specks), " in title, title
        labels = [t.get_text() for ax in fig.axes if ax.get_legend()
                  for t in ax.get_legend().get_texts()]  # fmt: skip
        (speck,) = [t for t in labels if "specks of 1 cell" in t]
        assert speck.endswith("took them in 30-50% of the 50 kept samples (agreement.npy), "
                              "the other concepts' cells 100%"), speck  # fmt: skip
    finally:
        plt.close(fig)


@pytest.mark.parametrize("count", [2, 8, 9, 10])
def test_the_listing_and_the_legend_give_the_specks_one_line(count, capsys):
    """room1ldk5 (seed 0): fit listed "8 specks of 1 cell where no word was heard (concepts 2,
    3, 4, 43, 68, 70, 81, 87; concepts.json lists them)", its semantic map's legend "8 specks
    of 1 cell, no words heard: [2], [3], [4], [43], [68], [70], ... in concepts.json": the same
    specks, named by two rules in other words. Both now give one line, naming 8 (9 when one is
    over: shown_count), the rest counted."""
    from spcopyro.cli.concept_listing import print_concepts
    from spcopyro.figures.map_pieces import concept_handles, legend_concepts

    result = _rooms_and_specks(specks=count)
    print_concepts(result)
    (line,) = [s for s in capsys.readouterr().out.splitlines() if s.startswith("  + ")]
    labels = [h.get_label() for h in concept_handles(result, np.zeros((count + 2, 3)))]
    (legend,) = [t for t in labels if "speck" in t]
    text, support = legend.split("\n")
    assert line == f"  + {text}: {support.strip()}", (line, legend)
    ids = [str(c) for c in range(2, count + 2)]
    named = ids if count <= 9 else ids[:8]
    more = "" if count <= 9 else f", ... ({count - 8} more)"
    assert text == (f"{count} specks of 1 cell where under 0.1 words were heard (concepts "
                    f"{', '.join(named)}{more}; concepts.json lists them)")  # fmt: skip
    assert legend_concepts(result) == {0, 1} | {int(c) for c in named}


def test_fit_counts_the_specks_among_the_concepts_in_use(tmp_path, capsys):
    """A short original-code fit leaves specks; its summary line counts them as specks."""
    from spcopyro.cli.main import main
    from spcopyro.synthetic import HouseSpec, write_synthetic

    house = write_synthetic(
        tmp_path / "d", seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3)
    )
    out = tmp_path / "fit"
    argv = ["fit", str(house), "--out", str(out), "--sweeps", "20", "--preset", "original-code",
            "--gamma", "3", "--concepts", "20", "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    text = capsys.readouterr().out
    concepts = json.loads((out / "concepts.json").read_text())
    free = sum(c["cells"] for c in concepts)
    area = SpCoResult.load(out).grid.resolution ** 2  # m^2 of one of the labels' cells
    specks = sum(is_speck(c["cells"], c["words_heard"], free, area) for c in concepts)
    assert specks > 0  # the test would say nothing without one
    (line,) = [s for s in text.splitlines() if s.startswith("fitted ")]
    assert line.endswith(f"; {len(concepts)} concepts in use ({specks} of them specks)"), line
    assert "of the 10 kept samples (the marginals)" in text


def test_concepts_json_marks_the_specks_with_their_support(tmp_path):
    """concepts.json listed a one-cell speck like a room (only "no words heard here" told)."""
    _rooms_and_specks().save(tmp_path)
    concepts = json.loads((tmp_path / "concepts.json").read_text())
    assert [(c["concept"], c["speck"], c["support"]) for c in concepts] == [
        (0, False, 1.0),
        (1, False, 1.0),
        (2, True, 0.3),
        (3, True, 0.5),
    ]


def test_a_concept_that_heard_under_a_tenth_of_an_utterance_is_a_speck(capsys):
    """The reach share (``coarse``'s footprint_reach_share 0.2 since 2026-12-06) gives nearly
    every cell of a room a small positive count: room1dk5's concept 58, one cell that heard
    0.013 of an utterance, was listed as a concept and answered ``where`` while the rule asked
    for no word heard at all. Under SPECK_WORDS utterances on under SPECK_SHARE of the free
    cells is a speck; SPECK_WORDS or more, or SPECK_SHARE of the cells or more, is not. The
    listing reads ``heard`` in utterances: the model's counts over ``word_scaling``."""
    import dataclasses

    from spcopyro.cli.concept_listing import print_concepts
    from spcopyro.config import DataPreparation
    from spcopyro.results.concept_words import SPECK_SHARE, SPECK_WORDS
    from spcopyro.results.specks import speck_concepts

    assert (SPECK_WORDS, SPECK_SHARE) == (0.1, 0.005)
    a = 0.0025  # m^2 of a 0.05 m cell
    assert is_speck(1, 0.013, 1000, a) and is_speck(4, 0.0999, 1000, a)
    assert is_speck(1, 0.0, 1000, a)
    assert not is_speck(1, 0.1, 1000, a) and not is_speck(2, 0.3, 1000, a)  # several at one spot
    assert not is_speck(5, 0.0, 1000, a)  # 0.5 % of the free cells: no speck
    assert not is_speck(1, None, 1000, a)  # a result that does not know its counts
    result = _rooms_and_specks(specks=3)
    result = dataclasses.replace(result, preparation=DataPreparation(word_scaling=10.0))
    result.concept_totals[2:, 2] = [0.13, 0.999, 1.0]  # model counts: 0.013, 0.0999, 0.1 heard
    assert result.heard(2) == pytest.approx(0.013)
    assert speck_concepts(result) == [2, 3]
    print_concepts(result)
    out = capsys.readouterr().out
    assert "  + 2 specks of 1 cell where under 0.1 words were heard (concepts 2, 3; " in out
    assert "  concept   4:      1 cell   0.1 words" in out, out  # listed as a concept


def test_a_concept_of_half_a_square_metre_or_more_is_no_speck():
    """The share alone is relative to the map: on a house of 1.94 million cells at 0.05 m, 0.5 %
    is 9,722 cells (24 m^2), and whole rooms where no word was said were called specks (and
    joined by ``vi``). A speck also covers under SPECK_AREA (0.5 m^2): at the bound no speck,
    just under it one. A cell area that is no area is refused."""
    import dataclasses

    from spcopyro.results.concept_words import SPECK_AREA, speck_sized
    from spcopyro.results.specks import speck_concepts

    assert SPECK_AREA == 0.5
    big = 1_944_514  # free cells at 0.05 m
    assert is_speck(199, 0.0, big, 0.0025)  # 0.4975 m^2
    assert not is_speck(200, 0.0, big, 0.0025)  # 0.5 m^2: under the share, not the area
    assert not is_speck(9_000, 0.0, big, 0.0025)  # a 22.5 m^2 room (0.46 % of the cells)
    assert speck_sized(199, big, 0.0025) and not speck_sized(200, big, 0.0025)
    assert not speck_sized(10, 1000, 0.0025)  # 1 %: the share still binds
    for bad in (0.0, -1.0, float("nan"), float("inf"), True):
        with pytest.raises(ValueError, match="cell_area"):
            is_speck(1, 0.0, 1000, bad)
    # a result on 0.75 m cells (0.5625 m^2): its one-cell concepts are no specks
    result = _rooms_and_specks()
    assert speck_concepts(result) == [2, 3]
    coarse = OccupancyGrid(result.grid.occupancy, 0.75, result.grid.origin)
    assert speck_concepts(dataclasses.replace(result, grid=coarse)) == []
