"""Image features (spcopyro.features): preprocessing, weights loading, place head, extraction.

No test downloads anything: TORCH_HOME points into tmp_path and torch.hub's downloader is
replaced by one that fails. The backbone is the real torchvision AlexNet with seeded random
weights; checkpoints are saved by the tests themselves and read back through the real code path.
"""

from __future__ import annotations

import argparse
import copy
import logging
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from torchvision.models import AlexNet_Weights

from spcopyro.data import Observations, load_house, save_house
from spcopyro.features.backbone import (
    CheckpointError,
    WeightsNotFoundError,
    load_alexnet,
    load_state_dict_file,
    torchvision_cache_file,
)
from spcopyro.features.cli import add_parser
from spcopyro.features.distill import distillation_report, kl_divergence, top1_agreement
from spcopyro.features.extract import (
    extract_features,
    extract_to_csv,
    frozen_inputs,
    resolve_device,
    write_features_csv,
)
from spcopyro.features.head import (
    PlaceClassifier,
    encode_labels,
    load_head,
    save_head,
    train_head,
)
from spcopyro.features.images import (
    IMAGENET_MEAN,
    IMAGENET_STD,
    ImageReadError,
    UnreadableImagesError,
    list_images,
    make_transform,
    read_image,
)

CACHE_NAME = "alexnet-owt-7be5be79.pth"  # torchvision's file for AlexNet_Weights.IMAGENET1K_V1


pytestmark = pytest.mark.usefixtures("no_download")  # conftest: own torch cache, no download


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory) -> tuple[Path, dict[str, torch.Tensor]]:
    """A full AlexNet state dict (random weights, seed 1) saved with torch.save."""
    path = tmp_path_factory.mktemp("weights") / "alexnet-random.pth"
    state = load_alexnet("random", seed=1).state_dict()
    torch.save(state, path)
    return path, state


@pytest.fixture(scope="module")
def pristine() -> PlaceClassifier:
    return PlaceClassifier.load("random", seed=0)


@pytest.fixture
def model(pristine) -> PlaceClassifier:
    return copy.deepcopy(pristine)


def _write(path: Path, bgr: np.ndarray) -> Path:
    assert cv2.imwrite(str(path), bgr)
    return path


def _solid(h: int, w: int, bgr: tuple[int, int, int]) -> np.ndarray:
    image = np.zeros((h, w, 3), dtype=np.uint8)  # [H, W, 3] BGR
    image[:] = bgr
    return image


@pytest.fixture
def images_dir(tmp_path) -> Path:
    """Five small images of different colours and sizes."""
    folder = tmp_path / "images"
    folder.mkdir()
    rng = np.random.default_rng(3)
    for i in range(5):
        h, w = 48 + 8 * i, 64 + 4 * i
        image = rng.integers(0, 256, size=(h, w, 3), dtype=np.uint8)
        _write(folder / f"{i:05d}.{'png' if i % 2 else 'jpg'}", image)
    return folder


# --------------------------------------------------------------------------------------------
# images and preprocessing
# --------------------------------------------------------------------------------------------


def test_read_image_is_rgb_and_converts_grey_and_alpha(tmp_path):
    red = read_image(_write(tmp_path / "red.png", _solid(4, 5, (0, 0, 255))))  # BGR red
    assert red.shape == (4, 5, 3) and red.dtype == np.uint8
    assert red[0, 0].tolist() == [255, 0, 0]
    grey = read_image(_write(tmp_path / "grey.png", np.full((3, 2), 77, dtype=np.uint8)))
    assert grey.shape == (3, 2, 3) and (grey == 77).all()
    rgba = np.zeros((2, 2, 4), dtype=np.uint8)
    rgba[..., 1] = 200
    rgba[..., 3] = 255
    assert read_image(_write(tmp_path / "rgba.png", rgba))[0, 0].tolist() == [0, 200, 0]


def test_a_16_bit_image_reads_as_opencv_reads_it_and_a_dim_one_is_warned_of(
    tmp_path, caplog, monkeypatch
):
    """A 12-bit camera's frames saved as 16-bit PNG read nearly black (OpenCV keeps the high
    byte), without a word."""
    import spcopyro._util.messages as messages

    monkeypatch.setattr(messages, "_WARNED", set())
    rng = np.random.default_rng(0)
    full = rng.integers(0, 65536, (6, 5, 3)).astype(np.uint16)  # [H, W, 3] BGR
    grey = rng.integers(0, 65536, (6, 5)).astype(np.uint16)
    for name, image in (("full.png", full), ("grey.png", grey)):
        path = _write(tmp_path / name, image)
        as_opencv = cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
        np.testing.assert_array_equal(read_image(path), as_opencv)  # the same pixels as before
    assert not caplog.records
    dim = tmp_path / "camera"
    dim.mkdir()
    twelve_bit = (full >> 4).astype(np.uint16)  # values up to 4095
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        for k in range(2):
            assert read_image(_write(dim / f"{k}.png", twelve_bit)).max() <= 15
    [said] = [r.getMessage() for r in caplog.records]  # once a folder
    assert said.startswith(f"{dim / '0.png'}: a 16-bit image whose brightest value is ")
    assert "of 65535 (a 10- or 12-bit camera's range?)" in said


def test_read_image_errors_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="nothere.jpg: image file not found"):
        read_image(tmp_path / "nothere.jpg")
    garbage = tmp_path / "garbage.jpg"
    garbage.write_bytes(b"this is not a jpeg")
    with pytest.raises(ImageReadError, match="garbage.jpg: OpenCV cannot decode"):
        read_image(garbage)
    empty = tmp_path / "empty.png"
    empty.write_bytes(b"")
    with pytest.raises(ImageReadError, match="empty.png: empty file"):
        read_image(empty)
    ok, encoded = cv2.imencode(".jpg", np.random.default_rng(0).integers(0, 256, (64, 64, 3)))
    assert ok
    truncated = tmp_path / "truncated.jpg"
    truncated.write_bytes(encoded.tobytes()[: encoded.size // 2])
    with pytest.raises(ImageReadError, match="truncated.jpg"):
        read_image(truncated)


def test_transform_shape_and_normalisation_by_hand():
    image = np.empty((480, 640, 3), dtype=np.uint8)  # [H, W, 3] RGB
    image[:] = (10, 128, 250)
    out = make_transform()(image)
    assert out.shape == (3, 224, 224) and out.dtype == torch.float32
    for c, value in enumerate((10, 128, 250)):
        expected = (value / 255 - IMAGENET_MEAN[c]) / IMAGENET_STD[c]
        assert torch.allclose(out[c], torch.full((224, 224), expected), atol=1e-6)


def test_transform_resizes_shorter_side_then_crops_the_centre():
    # 300 x 400 (H x W): black with a white band in the leftmost 50 columns. Resized to
    # 256 x 341, the band is 50 * 256/300 = 42.7 columns wide; the 224 crop starts at column
    # (341 - 224) // 2 = 58, so no white survives; a band reaching column 250 of 400 does.
    image = np.zeros((300, 400, 3), dtype=np.uint8)
    image[:, :50] = 255
    black = torch.tensor([(0 - m) / s for m, s in zip(IMAGENET_MEAN, IMAGENET_STD, strict=True)])
    out = make_transform()(image)
    assert torch.allclose(out, black[:, None, None].expand(3, 224, 224), atol=1e-6)
    image[:, :250] = 255
    out = make_transform()(image)  # white up to column 250 * 256/300 - 58 = 155 of the crop
    assert (out[:, :, :150] > 2.0).all() and torch.allclose(out[:, :, 160:], black[:, None, None])


def test_transform_matches_torchvisions_preset_for_the_weights():
    image = np.random.default_rng(1).integers(0, 256, size=(120, 170, 3), dtype=np.uint8)
    ours = make_transform()(image)
    preset = AlexNet_Weights.IMAGENET1K_V1.transforms()(torch.from_numpy(image).permute(2, 0, 1))
    assert ours.shape == preset.shape == (3, 224, 224)
    one_grey_level = 1.0 / (255 * min(IMAGENET_STD))  # the two resize kernels round differently
    assert (ours - preset).abs().max() <= one_grey_level + 1e-6


def test_list_images_orders_like_load_house(tmp_path):
    flat = tmp_path / "flat"
    flat.mkdir()
    for name in ("b.jpg", "c.jpeg"):
        _write(flat / name, _solid(2, 2, (1, 2, 3)))
    _write(flat / "a.png", _solid(2, 2, (1, 2, 3))).rename(flat / "a.PNG")  # suffix case
    (flat / "notes.txt").write_text("not an image")
    assert [p.name for p in list_images(flat)] == ["a.PNG", "b.jpg", "c.jpeg"]

    house = tmp_path / "house"
    for k, names in ((10, ["00001.jpg"]), (2, ["00002.jpg", "00001.jpg"]), (0, ["00001.jpg"])):
        (house / f"img_{k}").mkdir(parents=True)
        for name in names:
            _write(house / f"img_{k}" / name, _solid(2, 2, (1, 2, 3)))
    (house / "Ft.csv").write_text("1\n")
    got = [f"{p.parent.name}/{p.name}" for p in list_images(house)]
    assert got == ["img_0/00001.jpg", "img_2/00001.jpg", "img_2/00002.jpg", "img_10/00001.jpg"]

    _write(house / "stray.jpg", _solid(2, 2, (1, 2, 3)))
    with pytest.raises(ValueError, match="both images"):
        list_images(house)
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match="empty: no images"):
        list_images(tmp_path / "empty")
    with pytest.raises(FileNotFoundError, match="missing: image folder not found"):
        list_images(tmp_path / "missing")


# --------------------------------------------------------------------------------------------
# backbone weights
# --------------------------------------------------------------------------------------------


def test_missing_imagenet_weights_say_how_to_get_them(tmp_path):
    expected = tmp_path / "torch_home" / "hub" / "checkpoints" / CACHE_NAME
    assert torchvision_cache_file() == expected
    with pytest.raises(WeightsNotFoundError) as info:
        load_alexnet("imagenet")  # would download without the check (here: AssertionError)
    message = str(info.value)
    assert str(expected) in message and "TORCH_HOME" in message
    # what a library caller passes, then features' flag (messages.setting)
    assert "(or pass download=True (features's --download))" in message
    assert "checkpoint with weights=PATH (features's --weights PATH);" in message
    assert "or weights='random' (features's --weights random) (features then" in message
    assert isinstance(info.value, FileNotFoundError)
    with pytest.raises(
        WeightsNotFoundError, match="nope.pth: backbone weights file not found"
    ) as info:
        PlaceClassifier.load(tmp_path / "nope.pth")
    assert "(weights (features's --weights) takes 'imagenet', 'random' or" in str(info.value)


def test_checkpoint_round_trip_through_file_and_torchvision_cache(checkpoint, tmp_path):
    path, state = checkpoint
    from_file = load_alexnet(path).state_dict()
    assert from_file.keys() == state.keys()
    assert all(torch.equal(from_file[k], state[k]) for k in state)
    assert not load_alexnet(path).training  # eval mode: dropout off

    # The same file as torchvision's cached ImageNet weights: read by the real weights API.
    cache = torchvision_cache_file()
    cache.parent.mkdir(parents=True)
    cache.symlink_to(path)
    from_cache = load_alexnet("imagenet").state_dict()
    assert all(torch.equal(from_cache[k], state[k]) for k in state)
    model = PlaceClassifier.load("imagenet")
    assert model.num_classes == 1000 and model.weights.pretrained
    assert not PlaceClassifier.load("random").weights.pretrained


def test_random_weights_are_seeded_and_leave_the_global_rng_alone():
    before = torch.random.get_rng_state()
    a, b = load_alexnet("random", seed=5), load_alexnet("random", seed=5)
    c = load_alexnet("random", seed=6)
    assert torch.equal(torch.random.get_rng_state(), before)
    assert torch.equal(a.features[0].weight, b.features[0].weight)
    assert not torch.equal(a.features[0].weight, c.features[0].weight)


def test_bad_checkpoints_give_clear_errors(tmp_path):
    garbage = tmp_path / "garbage.pth"
    garbage.write_bytes(b"\x00not a checkpoint")
    with pytest.raises(CheckpointError, match="garbage.pth: not a readable torch checkpoint"):
        load_alexnet(garbage)
    tensor_file = tmp_path / "tensor.pth"
    torch.save(torch.zeros(3), tensor_file)
    with pytest.raises(CheckpointError, match="tensor.pth: expected a state dict"):
        load_alexnet(tensor_file)
    partial = tmp_path / "partial.pth"
    torch.save({"classifier.6.weight": torch.zeros(5, 4096)}, partial)
    with pytest.raises(CheckpointError, match=r"partial.pth: does not fit .*features.0.weight"):
        load_alexnet(partial)
    other = tmp_path / "other.pth"
    torch.save({"fc.weight": torch.zeros(2, 2)}, other)
    with pytest.raises(CheckpointError, match="other.pth: not an AlexNet state dict"):
        load_alexnet(other)
    wrapped = tmp_path / "wrapped.pth"
    torch.save({"state_dict": {"module.a": torch.ones(2), "module.b": torch.zeros(1)}}, wrapped)
    loaded = load_state_dict_file(wrapped)
    assert list(loaded) == ["a", "b"] and torch.equal(loaded["a"], torch.ones(2))


# --------------------------------------------------------------------------------------------
# place head
# --------------------------------------------------------------------------------------------


def test_place_classifier_shapes_and_split(model):
    pixels = torch.randn(2, 3, 224, 224, generator=torch.Generator().manual_seed(0))
    model.replace_head(7, [f"p{k}" for k in range(7)])
    with torch.no_grad():
        assert model.embed(pixels).shape == (2, 4096)
        assert torch.equal(model(pixels), torch.zeros(2, 7))  # a new head is zero
        assert torch.equal(model.probabilities(pixels), torch.full((2, 7), 1 / 7))
        model.head.weight.normal_(generator=torch.Generator().manual_seed(1))
        full = model(pixels)
        for tune_layers, width in ((0, 4096), (1, 4096), (2, 9216)):
            inputs = model.prefix(pixels, tune_layers)
            assert inputs.shape == (2, width)
            assert torch.allclose(model.suffix(inputs, tune_layers), full, atol=1e-6)
    with pytest.raises(ValueError, match="3 class names for a head of 7"):
        model.replace_head(7, ["a", "b", "c"])


def test_encode_labels():
    classes, labels = encode_labels(["kitchen", "bedroom", "kitchen", " toilet "])
    assert classes == ("bedroom", "kitchen", "toilet")
    assert labels.tolist() == [1, 0, 1, 2]
    with pytest.raises(ValueError, match="image 1 is empty"):
        encode_labels(["kitchen", "  "])


def _red_blue(tmp_path) -> tuple[list[Path], list[str]]:
    colours = [((0, 0, 255), "red"), ((255, 0, 0), "blue"), ((0, 0, 240), "red")]
    colours.append(((240, 0, 0), "blue"))
    paths = [_write(tmp_path / f"{i}.png", _solid(60, 80, c)) for i, (c, _) in enumerate(colours)]
    return paths, [name for _, name in colours]


def test_fine_tuning_on_labels_lowers_the_loss(model, tmp_path):
    paths, names = _red_blue(tmp_path)
    classes, labels = encode_labels(names)
    model.replace_head(len(classes), classes)
    inputs = frozen_inputs(model, paths, progress=False)  # [4, 4096]
    backbone_before = model.network.classifier[4].weight.clone()
    result = train_head(model, inputs, labels, mode="labels", epochs=50, lr=1e-2)
    # Balanced labels and a zero head: the start is the uniform histogram, loss log 2, and no
    # bias can lower it -- only weights that use the images can.
    assert result.initial_loss == pytest.approx(math.log(2), abs=1e-6)
    assert result.final_loss < 0.3
    assert len(result.epoch_losses) == 50
    assert torch.equal(model.network.classifier[4].weight, backbone_before)  # backbone frozen
    predicted = extract_features(model, paths, progress=False).argmax(axis=1)
    assert predicted.tolist() == labels.tolist()


def test_train_head_rejects_bad_targets(model):
    model.replace_head(3)
    inputs = torch.zeros(2, 4096)
    with pytest.raises(ValueError, match="labels mode needs"):
        train_head(model, inputs, torch.zeros(2, 3), mode="labels")
    with pytest.raises(ValueError, match="distill mode needs"):
        train_head(model, inputs, torch.zeros(2, dtype=torch.int64), mode="distill")
    with pytest.raises(ValueError, match="target histogram 1 sums to 0"):
        train_head(model, inputs, torch.tensor([[1.0, 0, 0], [0, 0, 0]]), mode="distill")
    with pytest.raises(ValueError, match="tune_layers must be 0, 1 or 2"):
        train_head(model, inputs, torch.zeros(2, dtype=torch.int64), mode="labels", tune_layers=3)


def test_head_file_round_trip_with_a_tuned_layer(model, pristine, tmp_path, checkpoint, caplog):
    paths, names = _red_blue(tmp_path)
    classes, labels = encode_labels(names)
    model.replace_head(len(classes), classes)
    inputs = frozen_inputs(model, paths, tune_layers=1, progress=False)
    train_head(model, inputs, labels, mode="labels", tune_layers=1, epochs=3, lr=1e-3)
    assert not torch.equal(
        model.network.classifier[4].weight, pristine.network.classifier[4].weight
    )
    head_path = save_head(model, tmp_path / "head.pt", mode="labels")

    fresh = copy.deepcopy(pristine)
    info = load_head(fresh, head_path)
    assert info.class_names == ("blue", "red") and info.tune_layers == 1 and info.mode == "labels"
    assert fresh.names == ("blue", "red")
    state, expected = fresh.network.state_dict(), model.network.state_dict()
    assert all(torch.equal(state[k], expected[k]) for k in expected)
    assert np.array_equal(
        extract_features(fresh, paths, progress=False),
        extract_features(model, paths, progress=False),
    )
    with pytest.raises(
        CheckpointError, match="alexnet-random.pth: not an spcopyro place-head"
    ) as e:
        load_head(fresh, checkpoint[0])
    # the setting in messages.setting's one form: load_head runs under `spcopyro features`
    assert str(e.value).endswith(
        "for backbone weights use weights=PATH (features's --weights PATH)"
    )
    # a head put on another backbone than it was trained on is loaded, with a warning
    other = PlaceClassifier.load(checkpoint[0])
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        load_head(fresh, head_path)  # its own backbone: nothing to say
        assert not [r for r in caplog.records if "was trained on the backbone" in r.getMessage()]
        load_head(other, head_path)
    said = [
        r.getMessage() for r in caplog.records if "was trained on the backbone" in r.getMessage()
    ]
    assert len(said) == 1 and "NOT pretrained" in said[0] and "alexnet-random.pth" in said[0]
    assert said[0].endswith(
        "pass the head's backbone as weights (features's --weights) and its seed as seed "
        "(features's --seed)"
    )  # it was trained on random weights; library callers are told the keywords too
    with pytest.raises(FileNotFoundError, match="none.pt: head file not found"):
        load_head(fresh, tmp_path / "none.pt")


@pytest.mark.dataset
def test_distillation_on_a_handful_of_dataset_images_lowers_the_loss(dataset_root, model):
    obs = load_house(dataset_root / "room1dk5").observations
    assert obs.image_paths is not None
    paths, targets = obs.image_paths[:6], obs.image_features[:6]  # [6, 205]
    model.replace_head(targets.shape[1])
    inputs = frozen_inputs(model, paths, progress=False)
    result = train_head(model, inputs, torch.as_tensor(targets), mode="distill", epochs=30, lr=1e-2)
    # A zero head predicts 1/K: loss = mean_n sum_k p_nk log(K p_nk), computed here by hand.
    p = targets / targets.sum(axis=1, keepdims=True)
    by_hand = np.mean([sum(x * math.log(205 * x) for x in row if x > 0) for row in p])
    assert result.initial_loss == pytest.approx(by_hand, rel=1e-5)
    assert result.final_loss < 0.5 * result.initial_loss


def test_kl_divergence_and_top1_by_hand():
    p = np.array([[0.5, 0.5, 0.0], [1.0, 0.0, 0.0]])
    q = np.array([[0.25, 0.25, 0.5], [0.5, 0.25, 0.25]])
    # row 0: 0.5 ln 2 + 0.5 ln 2 = ln 2; row 1: ln 2. Unnormalised input is normalised first.
    assert kl_divergence(p, q) == pytest.approx([math.log(2), math.log(2)])
    assert kl_divergence(p * 3, q * 7) == pytest.approx([math.log(2), math.log(2)])
    assert kl_divergence(p, p) == pytest.approx([0.0, 0.0])
    assert kl_divergence(np.array([[0.5, 0.5]]), np.array([[1.0, 0.0]]))[0] == math.inf
    assert top1_agreement(p, q) == 0.5  # row 0 ties: first index (0) in both; row 1: 0 vs 0
    assert top1_agreement(p, np.array([[0, 1.0, 0], [0, 0, 1.0]])) == 0.0


@pytest.mark.dataset
def test_distillation_report_on_a_held_out_trial(dataset_root, model):
    house = load_house(dataset_root / "room1dk5")
    report = distillation_report(
        house, model=model, max_images_per_trial=3, epochs=5, lr=1e-2, progress=False
    )
    assert (report.train_trials, report.held_out_trial) == ((0, 1), 2)
    assert (report.num_train, report.num_test, report.num_classes) == (6, 3, 205)
    held_out = house.observations.image_features[house.observations.image_trial == 2][:3]
    p = held_out / held_out.sum(axis=1, keepdims=True)
    entropy = -np.sum(np.where(p > 0, p * np.log(np.where(p > 0, p, 1)), 0), axis=1)
    assert report.uniform_kl == pytest.approx(np.mean(math.log(205) - entropy))
    assert 0 <= report.top1 <= 1 and report.kl >= 0
    assert not report.pretrained
    assert "RANDOM weights" in report.text() and "mean little" in report.text()
    with pytest.raises(ValueError, match="must be distinct trials"):
        distillation_report(house, model=model, held_out_trial=7)


# --------------------------------------------------------------------------------------------
# extraction
# --------------------------------------------------------------------------------------------


def test_extraction_is_deterministic_in_eval_mode(model, images_dir):
    model.replace_head(5)
    model.head.weight.data.normal_(generator=torch.Generator().manual_seed(2))
    model.train()  # extraction must switch to eval (dropout off) by itself
    paths = list_images(images_dir)
    first = extract_features(model, paths, batch_size=2, progress=False)
    second = extract_features(model, paths, batch_size=2, progress=False)
    assert first.shape == (5, 5) and first.dtype == np.float64
    assert np.array_equal(first, second)
    one_by_one = extract_features(model, paths, batch_size=1, progress=False)
    assert np.allclose(one_by_one, first, rtol=0, atol=1e-6)
    assert np.allclose(first.sum(axis=1), 1.0, atol=1e-5)
    assert np.ptp(first, axis=0).max() > 0  # different images, different rows


def test_unreadable_images_are_all_reported_and_nothing_is_written(model, images_dir, tmp_path):
    (images_dir / "00001.png").write_bytes(b"broken")
    (images_dir / "00003.png").write_bytes(b"")
    out = tmp_path / "Ft.csv"
    with pytest.raises(UnreadableImagesError) as info:
        extract_to_csv(images_dir, out, model=model, progress=False)
    failed = [p.name for p, _ in info.value.failures]
    assert failed == ["00001.png", "00003.png"]
    assert str(images_dir / "00001.png") in str(info.value) and "2 of 5" in str(info.value)
    assert not out.exists()
    with pytest.raises(UnreadableImagesError, match="gone.jpg: image file not found"):
        extract_features(model, [images_dir / "00000.jpg", images_dir / "gone.jpg"])


def test_write_features_csv_full_precision_and_no_overwrite(tmp_path):
    features = np.array([[0.1, 1 / 3, 2e-300], [0.0, 0.5, 0.123456789012345678]])
    out = write_features_csv(tmp_path / "Ft.csv", features)
    lines = out.read_text().splitlines()
    assert len(lines) == 2 and all(len(line.split(",")) == 3 for line in lines)
    assert np.array_equal(
        np.array([[float(x) for x in line.split(",")] for line in lines]), features
    )
    with pytest.raises(FileExistsError, match="Ft.csv already exists") as info:
        write_features_csv(out, features)
    assert "pass overwrite=True (features's --overwrite) to replace it" in str(info.value)
    with pytest.raises(ValueError, match=r"feature \[0, 1\] is not finite or negative"):
        write_features_csv(tmp_path / "bad.csv", np.array([[0.5, -0.1]]), overwrite=True)


def test_resolve_device():
    assert resolve_device("cpu") == torch.device("cpu")
    with pytest.raises(ValueError, match="cpu or cuda"):
        resolve_device("meta")
    if not torch.cuda.is_available():
        with pytest.raises(ValueError, match="CUDA is not available"):
            resolve_device("cuda")


@pytest.mark.dataset
def test_extracted_ft_csv_loads_with_load_house_and_fits(dataset_root, model, tmp_path):
    from spcopyro.config import preset
    from spcopyro.fit.house import fit_house

    house = load_house(dataset_root / "room1dk5")
    obs = house.observations
    keep = np.concatenate([np.flatnonzero(obs.image_trial == k)[:2] for k in obs.trials])  # [6]
    small = Observations(
        image_features=obs.image_features[keep],
        image_xy=obs.image_xy[keep],
        image_trial=obs.image_trial[keep],
        utterances=obs.utterances,
        word_xy=obs.word_xy,
        word_trial=obs.word_trial,
        image_yaw=obs.image_yaw[keep],
        image_paths=tuple(obs.image_paths[i] for i in keep),
    )
    room = save_house(
        type(house)(name=house.name, grid=house.grid, observations=small), tmp_path / "data"
    )
    model.replace_head(205)
    model.head.weight.data.normal_(generator=torch.Generator().manual_seed(4))
    result = extract_to_csv(room, room / "Ft.csv", model=model, overwrite=True, progress=False)
    assert [f"{p.parent.name}/{p.name}" for p in result.paths] == [
        f"img_{k}/{n:05d}.jpg" for k in (0, 1, 2) for n in (1, 2)
    ]
    reloaded = load_house(room)
    assert reloaded.observations.image_features.shape == (6, 205)
    assert np.array_equal(reloaded.observations.image_features, result.features)
    assert np.array_equal(reloaded.observations.image_xy, obs.image_xy[keep])
    fitted = fit_house(reloaded, preset("paper-dp", num_concepts=5), sweeps=2, progress=False)
    assert fitted.label_image().shape == house.grid.shape


def test_cli_features_and_features_head(checkpoint, images_dir, tmp_path, capsys):
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command", required=True))

    def run(*argv: str) -> int:
        args = parser.parse_args([str(a) for a in argv])
        return args.func(args)

    labels = tmp_path / "labels.csv"
    labels.write_text(
        "# image,place\n"
        + "".join(
            f"images/{p.name},{'kitchen' if i < 3 else 'bedroom'}\n"
            for i, p in enumerate(list_images(images_dir))
        )  # fmt: skip
    )
    head = tmp_path / "head.pt"
    assert (
        run("features-head", labels, "--out", head, "--weights", checkpoint[0], "--epochs", 2) == 0
    )
    assert "cross-entropy" in capsys.readouterr().out
    out = tmp_path / "Ft.csv"
    assert (
        run("features", images_dir, "--out", out, "--weights", checkpoint[0], "--head", head) == 0
    )
    assert f"wrote {out}: 5 rows x 2 columns" in capsys.readouterr().out
    rows = [line.split(",") for line in out.read_text().splitlines()]
    assert len(rows) == 5 and {len(r) for r in rows} == {2}
    with pytest.raises(
        FileExistsError,
        match=r"Ft.csv already exists; pass overwrite=True \(features's --overwrite\)",
    ):
        run("features", images_dir, "--out", out, "--weights", checkpoint[0])
    with pytest.raises(WeightsNotFoundError, match=CACHE_NAME) as info:
        run("features", images_dir, "--out", tmp_path / "other.csv")
    assert "download=True (features's --download)" in str(info.value)
    # features-head's refusals name its own flags, not features'
    with pytest.raises(
        FileExistsError,
        match=r"head.pt already exists; pass overwrite=True \(features-head's --overwrite\)",
    ):
        run("features-head", labels, "--out", head, "--weights", "random")
    with pytest.raises(WeightsNotFoundError, match=CACHE_NAME) as info:
        run("features-head", labels, "--out", tmp_path / "h3.pt")
    assert "download=True (features-head's --download)" in str(info.value)
    assert "weights=PATH (features-head's --weights PATH)" in str(info.value)
    assert "features's" not in str(info.value)
    bad = tmp_path / "bad_labels.csv"
    bad.write_text("images/00000.jpg,kitchen\nimages/00001.png\n")
    with pytest.raises(ValueError, match="bad_labels.csv, line 2: expected IMAGE,PLACE"):
        run("features-head", bad, "--out", tmp_path / "h2.pt", "--weights", "random")


def test_an_image_missing_from_a_trial_is_an_error_naming_it(tmp_path):
    """Issue 22 item 2: one image missing from img_K/ used to give one row fewer than the poses,
    every later image's features on the wrong pose. Now an error before any work, naming the
    folder, the counts and the missing file."""
    house = tmp_path / "house"
    (house / "img_1").mkdir(parents=True)
    for name in ("00000.jpg", "00001.jpg", "00003.jpg"):  # 00002.jpg is missing
        _write(house / "img_1" / name, _solid(2, 2, (1, 2, 3)))
    (house / "pose_1.csv").write_text("".join(f"{k},0,0,1\n" for k in range(4)))
    with pytest.raises(ValueError, match=r"3 images but pose_1.csv has 4 poses.*00002\.jpg"):
        list_images(house)
    _write(house / "img_1" / "00002.jpg", _solid(2, 2, (1, 2, 3)))
    assert [p.name for p in list_images(house)] == [f"0000{k}.jpg" for k in range(4)]
