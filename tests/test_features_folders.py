"""``spcopyro features`` on a roboticist's own folders: where the images are not where it
looks, the error says where they are."""

from __future__ import annotations

import numpy as np
import pytest

cv2 = pytest.importorskip("cv2")
pytest.importorskip("torchvision")

from spcopyro.features.images import list_images  # noqa: E402


def _write(folder, count):
    folder.mkdir(parents=True, exist_ok=True)
    for number in range(count):
        cv2.imwrite(str(folder / f"{number:05d}.png"), np.zeros((8, 8, 3), np.uint8))


def test_no_images_names_the_folders_below_that_hold_them(tmp_path):
    """A camera driver's ``trial0/``, ``trial1/`` (not ``img_K/``) or an ``images/rgb/`` folder:
    the error said only "no images", and the user looked for a wrong suffix."""
    _write(tmp_path / "trial0", 2)
    _write(tmp_path / "trial1", 3)
    _write(tmp_path / "session" / "rgb", 1)
    with pytest.raises(FileNotFoundError) as caught:
        list_images(tmp_path)
    said = str(caught.value)
    assert f"{tmp_path}: no images" in said
    assert f"{tmp_path / 'session' / 'rgb'} (1)" in said
    assert f"{tmp_path / 'trial0'} (2), {tmp_path / 'trial1'} (3)" in said
    assert "img_0, img_1" in said


def test_no_images_anywhere_says_only_that(tmp_path):
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "readme.txt").write_text("x")
    with pytest.raises(FileNotFoundError) as caught:
        list_images(tmp_path)
    assert "images are in" not in str(caught.value)
    assert str(caught.value).endswith("in img_K/ folders)")
