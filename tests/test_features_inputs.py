"""What ``spcopyro features`` accepts as weights and images: checkpoints in the layouts public
AlexNet weights come in, a damaged torchvision cache file, image files it would otherwise skip.

Nothing is downloaded: TORCH_HOME points into tmp_path and torch.hub's downloader fails."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import torch
from torchvision.models import alexnet

from spcopyro.features.backbone import (
    CheckpointError,
    load_alexnet,
    load_state_dict_file,
    torchvision_cache_file,
)
from spcopyro.features.images import list_images

pytestmark = pytest.mark.usefixtures("no_download")  # conftest: own torch cache, no download


def test_checkpoint_with_data_parallel_features_loads(tmp_path):
    # PyTorch's ImageNet example (and the Places365 AlexNet, alexnet_places365.pth.tar) wrap
    # only model.features in nn.DataParallel: keys "features.module.0.weight", "classifier.1...".
    torch.manual_seed(0)
    net = alexnet(weights=None, num_classes=365)
    state = {k: v.clone() for k, v in net.state_dict().items()}
    net.features = torch.nn.DataParallel(net.features)
    assert "features.module.0.weight" in net.state_dict()
    path = tmp_path / "alexnet_places365.pth.tar"
    torch.save({"epoch": 3, "arch": "alexnet", "state_dict": net.state_dict()}, path)
    model = load_alexnet(path)
    assert model.classifier[6].out_features == 365
    for key, tensor in model.state_dict().items():
        assert torch.equal(tensor, state[key]), key
    wrapped = torch.nn.DataParallel(alexnet(weights=None)).state_dict()  # "module." prefix
    torch.save(wrapped, tmp_path / "prefixed.pth")
    assert set(load_state_dict_file(tmp_path / "prefixed.pth")) == set(alexnet().state_dict())


def test_caffe_alexnet_shapes_are_named(tmp_path):
    state = alexnet(weights=None).state_dict()
    state["features.0.weight"] = torch.zeros(96, 3, 11, 11)  # the original (Caffe) AlexNet
    torch.save(state, tmp_path / "caffe.pth")
    with pytest.raises(CheckpointError, match=r"features\.0\.weight .*Caffe AlexNet"):
        load_alexnet(tmp_path / "caffe.pth")


def test_damaged_cached_imagenet_file_is_a_clear_error():
    cache = torchvision_cache_file()
    cache.parent.mkdir(parents=True)
    cache.write_bytes(b"\xe3 not a torch file" * 50)
    with pytest.raises(CheckpointError, match="damaged: delete the file") as info:
        load_alexnet("imagenet")
    assert str(cache) in str(info.value)


def _write(path, shape=(6, 8, 3)):
    assert cv2.imwrite(str(path), np.full(shape, 90, dtype=np.uint8))
    return path


def test_images_of_another_type_are_not_silently_left_out(tmp_path):
    flat = tmp_path / "flat"
    flat.mkdir()
    for name in ("00001.jpg", "00002.bmp", "00003.png", "00004.webp"):
        _write(flat / name)
    with pytest.raises(ValueError, match=r"2 image file\(s\) .*00002\.bmp, 00004\.webp"):
        list_images(flat)
    (flat / "00002.bmp").unlink()
    (flat / "00004.webp").unlink()
    assert [p.name for p in list_images(flat)] == ["00001.jpg", "00003.png"]

    house = tmp_path / "house"
    (house / "img_0").mkdir(parents=True)
    _write(house / "img_0" / "00001.jpg")
    _write(house / "map.pgm", (6, 8))  # a house folder's own files are not its images
    assert [p.name for p in list_images(house)] == ["00001.jpg"]
    _write(house / "img_0" / "00002.tif")
    with pytest.raises(ValueError, match=r"img_0: 1 image file\(s\) .*00002\.tif"):
        list_images(house)
