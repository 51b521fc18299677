"""A study's inputs as QA met them: a map whose image has another name, names given twice,
options that contradict each other, figures of an earlier run, ``--report-only --dry-run``.

Nothing here fits more than a geometry baseline on a tiny house; most tests stop before a fit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from spcopyro.maps import OccupancyGrid
from spcopyro.maps.map_server import save_map
from spcopyro.study.sources import data_digest, resolve_source
from spcopyro.study.spec import DataSource


def _map_with_image(folder: Path, image: str) -> Path:
    """``folder/mymap.yaml`` naming ``image`` (another stem than the yaml's)."""
    grid = OccupancyGrid(np.zeros((6, 8), dtype=np.int8), 0.05, (0.0, 0.0, 0.0))
    saved = save_map(grid, folder / "saved.yaml")
    written = folder / image
    if Path(image).suffix == ".png":
        import cv2

        cv2.imwrite(str(written), np.full((6, 8), 254, dtype=np.uint8))
    else:
        saved.with_suffix(".pgm").rename(written)
    yaml = folder / "mymap.yaml"
    yaml.write_text(saved.read_text().replace("saved.pgm", image))
    saved.unlink()
    return yaml


@pytest.mark.parametrize("image", ["other.pgm", "pictures/other.png"])
def test_a_maps_digest_covers_the_image_its_yaml_names(tmp_path, image):
    (tmp_path / "pictures").mkdir()
    yaml = _map_with_image(tmp_path, image)
    data = resolve_source(DataSource("tour", "map", str(yaml)))
    before = data_digest(data, 0)
    assert data_digest(data, 0) == before
    picture = tmp_path / image
    picture.write_bytes(picture.read_bytes() + b"\0")  # the image edited
    assert data_digest(data, 0) != before
