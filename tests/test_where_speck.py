""" "Where is X?" calls the answer's region a speck by the rule of the concept listing and the
map's legend (:func:`~spcopyro.results.concept_words.is_speck`: under 0.5 % of the free cells
AND under 0.1 words heard there), not by its size alone: a toilet under 0.5 % of a large map
where the word was heard many times was told to the user as "a speck, not a place"."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hand_results import two_rooms

from spcopyro.cli.main import main
from spcopyro.results.concept_words import SPECK_SHARE, SPECK_WORDS, is_speck
from spcopyro.results.result import SpCoResult
from spcopyro.results.where import SMALL_REGION_FRACTION, answer_warnings

SPECK = "a speck, not a place"


def _heard(speck: float | None) -> SpCoResult:
    """two_rooms (its concept 2 one cell of 300, under 0.5 %; "kitchen" answered with it under
    pi) with ``speck`` words heard in concept 2 and 5 and 4 in the rooms; None: no counts kept."""
    result = two_rooms()
    if speck is None:
        return result
    totals = np.array([[3.0, 3.0, 5.0], [2.0, 2.0, 4.0], [1.0, 1.0, speck]])  # [L, 1 + M]
    return dataclasses.replace(result, concept_totals=totals)


def _speck_warnings(result: SpCoResult) -> list[str]:
    answer = result.where("kitchen", prior="pi")
    assert answer.concept == 2 and answer.region.sum() == 1
    return [w for w in answer.warnings if "the region is" in w]


def test_a_small_concept_where_words_were_heard_is_no_speck():
    """Three words heard on the one cell: the listing and the legend list it as a concept, and
    where no longer calls it "a speck, not a place" (nor strewn specks). The odds and the Bayes
    factor still warn: the answer is no clearer for it."""
    result = _heard(3.0)
    assert result.heard(2) == 3.0 and not is_speck(
        1, result.heard(2), result.grid.num_free, result.grid.resolution**2
    )
    warnings = result.where("kitchen", prior="pi").warnings
    assert not any(SPECK in w or "strewn" in w for w in warnings), warnings
    assert len(warnings) == 2 and "odds 1.17" in warnings[0] and "factor of 2.00" in warnings[1]
    # at the bound: SPECK_WORDS heard is no speck, just under it is one
    assert _speck_warnings(_heard(SPECK_WORDS)) == []
    (under,) = _speck_warnings(_heard(0.0999))
    assert "where 0.0999 words were heard (under 0.1): a speck, not a place" in under


@pytest.mark.parametrize(
    ("heard", "said"),
    [(0.0, "where no word was heard"), (0.013, "where 0.013 words were heard (under 0.1)")],
)
def test_a_small_concept_where_no_word_was_heard_is_still_a_speck(heard, said):
    (speck,) = _speck_warnings(_heard(heard))
    assert f"1 cell (0.01 m^2, 0.33% of the free cells, under 0.5%) {said}: {SPECK}" in speck
    assert "prior='area' (where's --prior area)" in speck and "size alone" not in speck


ALONE = "; judged by its size alone: no count of the words heard in it is known"


def test_a_result_without_counts_is_judged_by_size_and_says_so():
    (speck,) = _speck_warnings(_heard(None))
    assert f"under 0.5%): {SPECK} (eq. 19 with pi" in speck
    assert speck.endswith(f"weighs concepts by their share of the map){ALONE}")


def test_a_caller_without_counts_is_told_what_is_true_of_it():
    """answer_warnings called without ``heard`` (no result involved) judged the region by its
    size and said "this result keeps no count of the words heard in it": the ending now holds
    for any caller. 4 cells of 1000 (under 0.5 %), odds and Bayes factor 9: the speck alone."""
    posterior, prior, sizes = np.array([0.9, 0.1]), np.array([0.5, 0.5]), np.array([4, 996])
    (speck,) = answer_warnings(posterior, prior, sizes, prior_name="area", cell_area=0.0025)
    assert speck == (
        f"the region is 4 cells (0.01 m^2, 0.40% of the free cells, under 0.5%): {SPECK}{ALONE}"
    )
    assert "result" not in speck
    # the words heard, given: no speck where 0.1 were heard, a speck saying so under that
    assert answer_warnings(posterior, prior, sizes, heard=SPECK_WORDS, cell_area=0.0025) == ()
    (counted,) = answer_warnings(
        posterior, prior, sizes, prior_name="area", heard=0.0, cell_area=0.0025
    )
    assert counted.endswith(f"under 0.5%) where no word was heard: {SPECK}")


def test_a_small_region_in_pieces_is_judged_as_small_not_as_strewn():
    """A region under the speck share is a speck or a small place, never "strewn" (that warning
    is for regions not small themselves), whether or not its words heard are known."""
    region = np.zeros((20, 50), dtype=bool)
    region[0, 0] = region[0, 2] = region[5, 5] = region[9, 9] = True  # 4 pieces of 1 cell
    posterior, prior, sizes = np.array([0.9, 0.1]), np.array([0.5, 0.5]), np.array([4, 996])
    for heard in (None, 0.0, 3.0):
        warnings = answer_warnings(
            posterior, prior, sizes, region=region, heard=heard, cell_area=0.0025
        )
        assert not any("strewn" in w for w in warnings), (heard, warnings)
        assert any(SPECK in w for w in warnings) == (heard != 3.0), (heard, warnings)


def test_the_small_region_fraction_is_the_speck_share():
    """where's SMALL_REGION_FRACTION (strewn pieces, figure labels) is concept_words'
    SPECK_SHARE, not a copy of its value that could drift from it."""
    assert SMALL_REGION_FRACTION is SPECK_SHARE


@pytest.mark.parametrize("heard", [3.0, 0.0, None])
def test_where_on_a_saved_fit_warns_as_the_library_does(tmp_path, capsys, heard):
    """`spcopyro where` (torch-free: tests/test_cli_startup.py) reads the words heard from the
    saved ``result.npz`` (``concept_totals``) and prints the library's warnings, no more."""
    result = _heard(heard)
    out = result.save(tmp_path / "fit")
    loaded = SpCoResult.load(out)
    assert loaded.heard(2) == result.heard(2)
    assert main(["where", str(out), "kitchen", "--prior", "pi"]) == 0
    printed = [
        line.removeprefix("warning: ")
        for line in capsys.readouterr().err.splitlines()
        if line.startswith("warning: ")
    ]
    expected = result.where("kitchen", prior="pi").warnings
    assert printed == list(expected) == list(loaded.where("kitchen", prior="pi").warnings)
    assert any(SPECK in w for w in printed) == (heard != 3.0)


def test_where_on_a_saved_fit_with_words_heard_imports_no_torch(tmp_path):
    """The words heard come from the saved file, not from anything that needs torch."""
    from test_cli_startup import heavy_imports

    out = _heard(3.0).save(tmp_path / "fit")
    imported, printed = heavy_imports(["where", str(out), "kitchen", "--prior", "pi"])
    assert imported == [] and "'kitchen' is concept 2" in printed


def test_a_region_of_half_a_square_metre_or_more_is_no_speck():
    """On a big map a room where no word was said holds under 0.5 % of the free cells; the
    speck's area bound (SPECK_AREA, 0.5 m^2) keeps where from calling it "a speck, not a
    place", whether or not the words heard in it are known. 4 cells of 1000: specks at
    0.1249 m^2 a cell (0.4996 m^2), none at 0.125 (0.5 m^2), nor "strewn" (under the share)."""
    from spcopyro.results.concept_words import SPECK_AREA

    assert SPECK_AREA == 0.5
    region = np.zeros((20, 50), dtype=bool)
    region[0, 0] = region[0, 2] = region[5, 5] = region[9, 9] = True  # 4 pieces of 1 cell
    posterior, prior, sizes = np.array([0.9, 0.1]), np.array([0.5, 0.5]), np.array([4, 996])
    for heard in (None, 0.0):
        small = answer_warnings(
            posterior, prior, sizes, region=region, heard=heard, cell_area=0.1249
        )
        assert any(SPECK in w for w in small), (heard, small)
        room = answer_warnings(posterior, prior, sizes, region=region, heard=heard, cell_area=0.125)
        assert room == (), (heard, room)


def test_answer_warnings_takes_no_default_cell_area():
    """answer_warnings took ``cell_area=1.0`` by default, which since the speck's area bound
    (0.5 m^2) decides the speck warning: a caller that left it out was never told of a speck (4
    cells of 1 m^2 are none). The cell area is now a required keyword, as point_estimate's is."""
    posterior, prior, sizes = np.array([0.9, 0.1]), np.array([0.5, 0.5]), np.array([4, 996])
    with pytest.raises(TypeError, match="cell_area"):
        answer_warnings(posterior, prior, sizes, heard=0.0)
    (speck,) = answer_warnings(posterior, prior, sizes, heard=0.0, cell_area=0.0025)
    assert SPECK in speck
