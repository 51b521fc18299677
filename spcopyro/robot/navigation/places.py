"""A topological map of places (issue 27 item 2, SpCoTMHP's place graph).

Nodes: the connected regions of one concept on the fit's grid (4-connected components of
:meth:`~spcopyro.results.result.SpCoResult.label_image`), each with its area, centroid and the
concept's top words (none where no word was heard or the fit did not model its words) and its
name (:func:`~spcopyro.results.concept_names.concept_name`: the word ``where`` answers with it,
as ``spcopyro where`` would); regions smaller than ``min_area`` square metres are dropped (and
counted).
Edges: two regions whose cells touch (4-neighbours), with the length of the shared border
(number of touching cell pairs x the cell size) and whether it is a doorway (a border of at most
:data:`DOORWAY_WIDTH` metres). :meth:`PlaceGraph.route` is the shortest route over the edges,
weighted by the distance between the regions' centroids.

numpy and scipy only (no torch): ``spcopyro show OUT --graph`` imports it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import shortest_path

from spcopyro._util.messages import area_text, plural
from spcopyro.maps.regions import concept_regions, region_contacts
from spcopyro.results.concept_names import answered_words, concept_name
from spcopyro.results.concept_words import listed_top_words

__all__ = [
    "DEFAULT_MIN_AREA",
    "DOORWAY_WIDTH",
    "Passage",
    "Place",
    "PlaceGraph",
    "place_graph",
    "places_along",
    "telling_apart",
    "told_apart",
]

DEFAULT_MIN_AREA = 0.25
"""Square metres: smaller regions are not places."""

DOORWAY_WIDTH = 1.2
"""Metres: a shared border at most this long is a narrow passage (a doorway)."""


@dataclass(frozen=True)
class Place:
    """One node: a connected region of one concept."""

    id: int
    concept: int
    cells: int
    area: float
    """Square metres."""
    centroid: tuple[float, float]
    """World x, y (metres) of the mean of its cells' centres (may lie outside a concave one)."""
    words: tuple[str, ...]
    """The concept's top words, most probable first."""
    name: str
    """Its name, its concept's (:func:`~spcopyro.results.concept_names.concept_name`, the one
    rule of every output that names a region): its first answered word, else its top word,
    else ``concept N`` for a concept where no word was heard."""
    answers: tuple[str, ...] = ()
    """The words heard on the map whose ``where`` answer is its concept, most probable in the
    concept (p(word | concept)) first (:func:`~spcopyro.results.concept_names.answered_words`)."""

    @property
    def area_text(self) -> str:
        """Its area as ``show --graph`` and graph.png write it (square metres, no unit; as
        every output writes an area, :func:`~spcopyro._util.messages.area_text`)."""
        return area_text(self.area)


@dataclass(frozen=True)
class Passage:
    """One edge: two places whose cells touch."""

    a: int
    b: int
    border: float
    """Metres: touching 4-neighbour cell pairs x the cell size."""
    doorway: bool
    """The border is at most :data:`DOORWAY_WIDTH` long."""
    distance: float
    """Metres between the two centroids (the edge's weight in :meth:`PlaceGraph.route`)."""
    on_map: bool = False
    """Found on the robot's planning map, not on the fit's grid: the two places' cells touch
    there where the fit's coarser cells put a wall between them
    (:func:`~spcopyro.robot.navigation.hierarchy.with_map_passages`)."""
    passable: bool = True
    """The robot, its clearance kept, can cross from one place to the other within their cells
    and shared border (:func:`~spcopyro.robot.navigation.hierarchy.with_passability`; a place
    graph made without a robot counts every passage); :meth:`PlaceGraph.route` takes only
    these."""


@dataclass(frozen=True)
class PlaceGraph:
    """The place graph of a fit (:func:`place_graph`)."""

    places: tuple[Place, ...]
    passages: tuple[Passage, ...]
    regions: np.ndarray
    """[H, W] int64 the place id of every cell of the fit's grid, -1 elsewhere (walls, unknown,
    dropped regions)."""
    min_area: float
    dropped: int
    """How many regions were smaller than ``min_area``."""
    dropped_area: float
    """Their total area, square metres."""
    robot_checked: bool = False
    """Whether a robot's passability was checked
    (:func:`~spcopyro.robot.navigation.hierarchy.with_passability`); without it every passage
    counts and ``graph.json`` says ``"passable": null`` (unknown)."""

    def dropped_text(self, unit: str = "m^2") -> str:
        """``"2 regions under 0.25 m^2 left out"`` (``unit`` the square metres' spelling: graph.png
        writes "m²"), as ``show --graph`` prints it and graph.png's title writes it; ``""``
        where no region was left out (neither says "0 regions")."""
        if not self.dropped:
            return ""
        return f"{plural(self.dropped, 'region')} under {self.min_area:g} {unit} left out"

    def place_of(self, cell: np.ndarray) -> int:
        """The place of a grid cell ``(row, col)``: the region it lies in, else the nearest one
        (a wall cell, a dropped region or a cell off a coarser grid); -1 for an empty graph or a
        cell off the grid."""
        row, col = (int(v) for v in np.asarray(cell).reshape(2))
        height, width = self.regions.shape
        if not self.places or not (0 <= row < height and 0 <= col < width):
            return -1
        if self.regions[row, col] >= 0:
            return int(self.regions[row, col])
        _, (rows, cols) = ndimage.distance_transform_edt(self.regions < 0, return_indices=True)
        return int(self.regions[rows[row, col], cols[row, col]])

    def route(self, start: int, goal: int) -> list[int] | None:
        """Place ids from ``start`` to ``goal`` along the shortest route over the passable
        passages (centroid distances); None when no route joins them."""
        if start == goal:
            return [start]
        n = len(self.places)
        usable = [p for p in self.passages if p.passable]
        a = np.array([p.a for p in usable], dtype=np.int64)
        b = np.array([p.b for p in usable], dtype=np.int64)
        w = np.array([p.distance for p in usable])
        # a tiny floor keeps a zero-length edge (coincident centroids) an edge in the sparse graph
        matrix = coo_matrix((np.maximum(w, 1e-9), (a, b)), shape=(n, n)).tocsr()
        distance, predecessors = shortest_path(
            matrix, directed=False, indices=start, return_predecessors=True
        )
        if not np.isfinite(distance[goal]):
            return None
        path = [goal]
        while path[-1] != start:
            path.append(int(predecessors[path[-1]]))
        return path[::-1]

    def to_json(self) -> dict[str, object]:
        """The graph as plain JSON values (``graph.json``, ``navigate.json``)."""
        return {
            "places": [
                {"id": p.id, "concept": p.concept, "area_m2": p.area, "cells": p.cells,
                 "x": p.centroid[0], "y": p.centroid[1], "name": p.name,
                 "words": list(p.words), "answers": list(p.answers)}
                for p in self.places
            ],
            "passages": [
                {"a": e.a, "b": e.b, "border_m": e.border, "doorway": e.doorway,
                 "distance_m": e.distance, "on_map": e.on_map,
                 "passable": e.passable if self.robot_checked else None}
                for e in self.passages
            ],
            "min_area_m2": self.min_area,
            "doorway_width_m": DOORWAY_WIDTH,
            "dropped_regions": self.dropped,
            "dropped_area_m2": self.dropped_area,
        }  # fmt: skip


def place_graph(result: object, min_area: float = DEFAULT_MIN_AREA) -> PlaceGraph:
    """The place graph of a fit (:class:`~spcopyro.results.result.SpCoResult`; module docstring).

    Places are numbered largest first (ties in the order of concept, then raster order of the
    region's first cell).
    """
    grid = result.grid  # type: ignore[attr-defined]
    image = np.asarray(result.label_image())  # type: ignore[attr-defined]  # [H, W]
    cell_area = grid.resolution**2
    components, concept_of = concept_regions(image)  # [H, W] region id before dropping, [R]
    count = len(concept_of)
    sizes = np.bincount(components[components >= 0], minlength=count)  # [count]
    keep = sizes * cell_area >= min_area - 1e-12
    order = np.flatnonzero(keep)
    order = order[np.argsort(-sizes[order], kind="stable")]
    renumber = np.full(count + 1, -1, dtype=np.int64)  # index count: -1 stays -1
    renumber[order] = np.arange(order.size)
    regions = renumber[components]  # [H, W]

    ids = regions.ravel()
    inside = ids >= 0
    rows, cols = np.divmod(np.flatnonzero(inside), image.shape[1])
    xy = grid.cell_to_world(np.stack([rows, cols], axis=1)).reshape(-1, 2)  # [M, 2]
    n = order.size
    cells = np.bincount(ids[inside], minlength=n)
    centroid = np.stack([np.bincount(ids[inside], weights=xy[:, k], minlength=n)
                         for k in (0, 1)], axis=1) / np.maximum(cells, 1)[:, None]  # fmt: skip
    words: dict[int, tuple[str, ...]] = {}
    names: dict[int, str] = {}
    answers = answered_words(result, heard_only=True)  # concept -> its where-answered words
    places = []
    for node, region in enumerate(order):
        concept = int(concept_of[region])
        if concept not in words:  # none where no word was heard: its top words are the prior's
            top = listed_top_words(result, concept, 3)  # as concepts() lists them
            words[concept] = tuple(w for w, _ in top)
            names[concept] = concept_name(result, concept, answers)  # concept_names' rule
        places.append(Place(node, concept, int(cells[node]), float(cells[node] * cell_area),
                            (float(centroid[node, 0]), float(centroid[node, 1])),
                            words[concept], names[concept], answers.get(concept, ())))  # fmt: skip
    a, b, touching = region_contacts(regions)
    gap = np.hypot(*(centroid[a] - centroid[b]).T) if len(a) else np.zeros(0)
    border = touching * grid.resolution
    passages = tuple(
        Passage(int(i), int(j), float(length), bool(length <= DOORWAY_WIDTH + 1e-9), float(d))
        for i, j, length, d in zip(a, b, border, gap, strict=True)
    )
    return PlaceGraph(
        places=tuple(places),
        passages=passages,
        regions=regions,
        min_area=float(min_area),
        dropped=int((~keep).sum()),
        dropped_area=float(sizes[~keep].sum() * cell_area),
    )


def places_along(graph: PlaceGraph, cells: np.ndarray) -> tuple[int, ...]:
    """The places that ``cells`` ([K, 2] row, col on the fit's grid, e.g. a path's) pass
    through, in order, each run of one place once; cells off the grid or in no place skipped."""
    cells = np.asarray(cells).reshape(-1, 2)
    height, width = graph.regions.shape
    on = (cells[:, 0] >= 0) & (cells[:, 0] < height) & (cells[:, 1] >= 0) & (cells[:, 1] < width)
    ids = graph.regions[cells[on, 0], cells[on, 1]]
    ids = ids[ids >= 0]
    if not len(ids):
        return ()
    first = np.concatenate([[True], ids[1:] != ids[:-1]])
    return tuple(int(i) for i in ids[first])


def told_apart(
    graph: PlaceGraph, route: Sequence[int], words: Sequence[str] | None = None
) -> tuple[str, ...]:
    """``words`` (one per place id of ``route``; None: each place's name,
    :attr:`Place.name`) told apart where a name alone would mislead. A word that names several
    places of the route adds each one's concept (``sink (concept 3)``, ``sink (concept 7)``).
    Every word of a place that needs its id adds the place id instead (``bedroom (place 3)``: the
    ids of ``spcopyro show OUT --graph`` and navigate.json's ``route.places``), for each place that
    word names: a place needs its id where the route names it by two words (passed as its top
    word ``sink``, reached as the stop ``kitchen``: ``sink (place 5)``, ``kitchen (place 5)``) or
    where its word names another place of the same concept (two regions of one concept). A word
    naming a place id below 0 (in no place) stays as it is."""
    words = tuple(graph.places[p].name for p in route) if words is None else tuple(words)
    added = telling_apart(graph, route, words)
    return tuple(f"{word} ({how})" if how else word for word, how in zip(words, added, strict=True))


def telling_apart(graph: PlaceGraph, route: Sequence[int], words: Sequence[str]) -> list[str]:
    """What each word of ``words`` (one per place id of ``route``) adds to be told apart
    (:func:`told_apart`, which says why, and writes it in brackets after the word): ``"place
    5"`` (its place id), ``"concept 3"`` (its place's concept) or ``""`` (nothing); for a caller
    that writes more in the brackets (graph.png's place labels, their area:
    :func:`~spcopyro.robot.navigation.figure.place_graph_figure`)."""
    named: dict[str, set[int]] = {}  # word -> the places of the route it names
    called: dict[int, set[str]] = {}  # place -> the words the route names it by
    for word, place in zip(words, route, strict=True):
        named.setdefault(word, set()).add(place)
        called.setdefault(place, set()).add(word)

    def by_place(word: str) -> bool:  # some place this word names needs its id
        same = named[word]
        one_concept = len({graph.places[p].concept for p in same}) < len(same)
        return one_concept or any(len(called[p]) > 1 for p in same)

    return [
        "" if min(named[word]) < 0
        else f"place {place}" if by_place(word)
        else f"concept {graph.places[place].concept}" if len(named[word]) > 1
        else ""
        for word, place in zip(words, route, strict=True)
    ]  # fmt: skip
