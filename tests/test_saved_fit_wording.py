"""What a user of a saved fit reads (a QA pass): ``where``'s threshold line beside its region,
``navigate``'s route where two places share a top word, and ``trace.png``'s concept count beside
the reported map's."""

from __future__ import annotations

import dataclasses

import numpy as np
from hand_results import WORDS, two_rooms

from spcopyro.results.result import EmissionTable


def _tied_rooms():
    """tests/hand_results.py's two rooms without the speck, "kitchen" equally probable under
    both rooms' concepts: p(concept | kitchen) = 0.500 each under the area prior (150 cells
    each)."""
    result = two_rooms()
    labels = np.asarray(result.labels).copy()  # [N]
    labels[labels == 2] = 1  # the speck joins the right room: 150 cells a side
    w = np.array([[0.6, 0.2, 0.2], [0.6, 0.3, 0.1], [0.1, 0.45, 0.45]])  # [L, V]
    emissions = tuple(EmissionTable("words", WORDS, w) if t.name == "words" else t
                      for t in result.emissions)  # fmt: skip
    return dataclasses.replace(result, labels=labels, emissions=emissions)


def test_where_says_what_its_region_is_when_no_cell_exceeds_one_half(tmp_path, capsys):
    """A tie (p = 0.500) answered with a 150-cell region and "cells whose probability of being
    the place exceeds 0.5: 0" beside it, as if the two contradicted each other; the line now
    says the region's cells' probability and that the region is the most probable concept's."""
    from spcopyro.cli.main import main

    fit = _tied_rooms().save(tmp_path / "fit")
    assert main(["where", str(fit), "kitchen"]) == 0
    printed = capsys.readouterr().out
    assert "(p = 0.500, area prior" in printed and "region: 150 cells" in printed
    (line,) = [x for x in printed.splitlines() if x.startswith("cells whose probability")]
    assert line == (
        "cells whose probability of being the place exceeds 0.5: 0 (point estimate); the region "
        "is the cells of the word's most probable concept, not of p > 0.5: its 150 cells have "
        "p = 0.500, none of them above 0.5"
    )


def test_where_s_threshold_line_is_unchanged_when_the_region_is_above_one_half():
    from spcopyro.results.uncertainty import threshold_line

    probability = np.array([0.9, 0.8, 0.1, 0.6])  # [N]
    region = np.array([True, True, False, False])  # [N]
    assert threshold_line(probability, region, "marginals") == (
        "cells whose probability of being the place exceeds 0.5: 3 (marginals)"
    )
    mixed = threshold_line(probability, np.array([True, False, True, False]), "marginals")
    assert mixed.endswith("its 2 cells have p = 0.100-0.900, 1 of them above 0.5")
