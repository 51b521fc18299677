"""How sparse a house is: the statistics that tell a real house from a synthetic one.

:func:`house_statistics` measures a :class:`~spcopyro.data.House` (public or synthetic) the same
way: free cells (and their area), observed cells (free cells holding at least one placed image or
utterance, exactly the cells of :func:`spcopyro.data.cell_counts`), their density (observed /
free), images, utterances, trials, vocabulary, and the tour length (the summed distance between
consecutive image positions of each trial, in metres). :func:`statistics_table` puts several
houses in a markdown table, :func:`public_and_synthetic_statistics` measures the public houses
next to synthetic settings (issue #14 item 5: "report both").

Measured (``python -c "from spcopyro.synthetic.statistics import main; main()"``): the public
houses have 58-86 observed cells of 18,026-27,746 (density 0.29-0.43 %); the default synthetic
house 176 of 3,600 (4.9 %); :meth:`HouseSpec.public_like` ~70 of ~23,500 (0.30 %).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass

import numpy as np

from spcopyro._util.messages import plural
from spcopyro.config import DEFAULT_SNAP_DISTANCE
from spcopyro.data import House, place_observations
from spcopyro.synthetic.house import make_house
from spcopyro.synthetic.spec import HouseSpec

__all__ = [
    "HouseStatistics",
    "house_statistics",
    "public_and_synthetic_statistics",
    "statistics_table",
]


@dataclass(frozen=True)
class HouseStatistics:
    """The sparsity statistics of one house (see the module docstring)."""

    name: str
    resolution: float  # metres per cell
    free_cells: int
    free_area_m2: float
    observed_cells: int  # free cells holding >= 1 placed image or utterance
    image_cells: int  # free cells holding >= 1 placed image
    word_cells: int  # free cells holding >= 1 placed utterance
    images: int
    utterances: int
    trials: int
    vocabulary: int
    tour_m: float  # summed distance between consecutive images of each trial
    categories: int | None  # ground-truth categories (None: no truth)

    @property
    def density(self) -> float:
        """Observed cells / free cells."""
        return self.observed_cells / self.free_cells if self.free_cells else float("nan")

    def to_json(self) -> dict[str, object]:
        """The fields and the density as JSON values."""
        return {**asdict(self), "density": self.density}


def house_statistics(house: House, snap_distance: float = DEFAULT_SNAP_DISTANCE) -> HouseStatistics:
    """Measure ``house`` (observations placed as :func:`spcopyro.data.cell_counts` places them,
    snapping within ``snap_distance`` metres)."""
    grid, obs = house.grid, house.observations
    image_cell = place_observations(grid, obs.image_xy, snap_distance)[0]  # [T] (-1 unplaced)
    word_cell = place_observations(grid, obs.word_xy, snap_distance)[0]  # [U]
    image_cells = np.unique(image_cell[image_cell >= 0])
    word_cells = np.unique(word_cell[word_cell >= 0])
    observed = np.union1d(image_cells, word_cells)
    for modality in obs.modalities:
        cells = place_observations(grid, modality.xy, snap_distance)[0]
        observed = np.union1d(observed, cells[cells >= 0])
    xy, trial = obs.image_xy, obs.image_trial  # [T, 2], [T]
    step = np.linalg.norm(np.diff(xy, axis=0), axis=1)  # [T-1]
    tour = float(step[trial[1:] == trial[:-1]].sum())
    return HouseStatistics(
        name=house.name,
        resolution=float(grid.resolution),
        free_cells=int(grid.num_free),
        free_area_m2=float(grid.num_free * grid.resolution**2),
        observed_cells=int(observed.size),
        image_cells=int(image_cells.size),
        word_cells=int(word_cells.size),
        images=int(obs.num_images),
        utterances=int(obs.num_utterances),
        trials=len(obs.trials),
        vocabulary=len(obs.vocabulary),
        tour_m=tour,
        categories=None if house.category_names is None else len(house.category_names),
    )


def statistics_table(rows: Iterable[HouseStatistics]) -> str:
    """A markdown table, one line per house."""
    lines = [
        "| house | cell (m) | free cells | area (m²) | observed cells | density | images "
        "| utterances | trials | vocabulary | tour (m) | categories |",
        "|---|" + "---|" * 11,
    ]
    for s in rows:
        lines.append(
            f"| {s.name} | {s.resolution:g} | {s.free_cells} | {s.free_area_m2:.1f} "
            f"| {s.observed_cells} | {100 * s.density:.2f} % | {s.images} | {s.utterances} "
            f"| {s.trials} | {s.vocabulary} | {s.tour_m:.1f} "
            f"| {'—' if s.categories is None else s.categories} |"
        )
    return "\n".join(lines) + "\n"


def public_and_synthetic_statistics(
    public: Iterable[House] = (),
    synthetic: Mapping[str, HouseSpec] | None = None,
    seeds: Iterable[int] = range(5),
) -> list[HouseStatistics]:
    """The public houses given, then for each synthetic setting (name -> spec; default: the
    default house as ``dense`` and :meth:`HouseSpec.public_like` as ``sparse``) the mean over
    ``seeds`` of its houses' statistics (counts rounded to integers), named ``NAME (mean of k
    seeds)``."""
    rows = [house_statistics(house) for house in public]
    if synthetic is None:
        synthetic = {"dense": HouseSpec(), "sparse": HouseSpec.public_like()}
    seeds = tuple(seeds)
    for name, spec in synthetic.items():
        stats = [house_statistics(make_house(seed=s, spec=spec, name=name)) for s in seeds]
        mean = {
            key: float(np.mean([getattr(st, key) for st in stats]))
            for key in ("free_cells", "observed_cells", "image_cells", "word_cells", "images",
                        "utterances", "trials", "vocabulary", "tour_m", "free_area_m2")
        }  # fmt: skip
        rows.append(
            HouseStatistics(
                name=f"{name} (mean of {plural(len(seeds), 'seed')})",
                resolution=stats[0].resolution,
                categories=stats[0].categories,
                tour_m=mean.pop("tour_m"),
                free_area_m2=mean.pop("free_area_m2"),
                **{key: int(round(value)) for key, value in mean.items()},  # type: ignore[arg-type]
            )
        )
    return rows


def main() -> None:
    """Print the table for the public houses (when the dataset is found) and both settings."""
    from spcopyro.data import find_dataset_root, list_houses, load_house

    root = find_dataset_root()
    public = [load_house(root / name) for name in list_houses(root)] if root else []
    print(statistics_table(public_and_synthetic_statistics(public)))
