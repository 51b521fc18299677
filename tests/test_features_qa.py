"""``spcopyro features`` / ``features-head`` as a user runs them: damaged weights and heads,
the backbone a head was trained on, the options' checks, what the commands print.

Nothing is downloaded: TORCH_HOME points into tmp_path and torch.hub's downloader fails."""

from __future__ import annotations

import copy
import shlex
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from spcopyro.features.backbone import CheckpointError, load_alexnet, parse_weights
from spcopyro.features.extract import extract_features
from spcopyro.features.head import PlaceClassifier, load_head, save_head
from spcopyro.features.images import list_images

pytestmark = pytest.mark.usefixtures("no_download")  # conftest: own torch cache, no download


@pytest.fixture(scope="module")
def pristine() -> PlaceClassifier:
    return PlaceClassifier.load("random", seed=0)


@pytest.fixture
def model(pristine) -> PlaceClassifier:
    return copy.deepcopy(pristine)


@pytest.fixture
def images_dir(tmp_path) -> Path:
    """Three small random images."""
    folder = tmp_path / "images"
    folder.mkdir()
    rng = np.random.default_rng(0)
    for i in range(3):
        image = rng.integers(0, 256, size=(20 + i, 24, 3), dtype=np.uint8)
        assert cv2.imwrite(str(folder / f"{i:05d}.png"), image)
    return folder


def test_non_finite_weights_are_named_not_blamed_on_the_output_csv(model, images_dir, tmp_path):
    # A checkpoint with NaN weights ran the whole folder and then failed with "Ft.csv: feature
    # [0, 0] is not finite or negative", naming the output file instead of the weights.
    state = load_alexnet("random", seed=1).state_dict()
    state["features.3.weight"][0, 0, 0, 0] = float("nan")
    path = tmp_path / "diverged.pth"
    torch.save(state, path)
    with pytest.raises(CheckpointError, match=r"diverged.pth: features.3.weight holds 1 non-fin"):
        load_alexnet(path)
    model.replace_head(2)
    model.head.bias.data[0] = float("inf")
    head = save_head(model, tmp_path / "head.pt")
    with pytest.raises(CheckpointError, match=r"head.pt: classifier.6.bias holds non-finite"):
        load_head(copy.deepcopy(model), head)
    with pytest.raises(ValueError, match=r"00000.png: the network's output is not finite"):
        extract_features(model, list_images(images_dir), progress=False)


def test_unreadable_checkpoints_say_what_the_file_is_without_torchs_advice(tmp_path):
    # torch's own message (kilobytes, with "Re-running torch.load with weights_only set to False
    # will likely succeed", which no option here does) was passed on whole.
    whole = tmp_path / "whole_model.pth"
    torch.save(torch.nn.Linear(2, 2), whole)  # a pickled module, not a state dict
    garbage = tmp_path / "garbage.pth"
    garbage.write_bytes(b"not a checkpoint at all")
    for path, what in ((whole, "pickled Python object .*Linear.*state_dict"), (garbage, "no pick")):
        with pytest.raises(CheckpointError, match=f"{path.name}: not a readable torch .*{what}"):
            load_alexnet(path)
        with pytest.raises(CheckpointError) as info:
            load_head(
                PlaceClassifier(load_alexnet("random"), weights=parse_weights("random")), path
            )
        assert f"{path.name}: not a readable head file" in str(info.value)
        assert "weights_only" not in str(info.value) and len(str(info.value)) < 400


def test_head_backbone_check_compares_the_weights_not_the_path(
    tmp_path, monkeypatch, caplog, pristine
):
    # The check compared "checkpoint alex.pth" with "checkpoint /abs/alex.pth": the same file
    # by another path warned, another file at the same relative path did not. (The files'
    # bytes are all that identifies a checkpoint; the network here is the random one.)
    from spcopyro.features.backbone import WeightsSource

    def on(path: Path | str) -> PlaceClassifier:
        return PlaceClassifier(
            copy.deepcopy(pristine.network), weights=WeightsSource("file", Path(path))
        )

    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    (tmp_path / "a" / "alex.pth").write_bytes(b"the weights trained on")
    (tmp_path / "b" / "alex.pth").write_bytes(b"other weights")
    monkeypatch.chdir(tmp_path / "a")
    trained = on("alex.pth")
    trained.replace_head(2)
    head = save_head(trained, tmp_path / "head.pt")
    caplog.set_level("WARNING", logger="spcopyro")
    load_head(on(tmp_path / "a" / "alex.pth"), head)
    assert "trained on the backbone" not in caplog.text
    monkeypatch.chdir(tmp_path / "b")
    load_head(on("alex.pth"), head)
    assert "trained on the backbone checkpoint alex.pth" in caplog.text
    assert "(same name, other contents)" in caplog.text


def test_features_head_says_how_to_run_the_head_on_its_own_backbone(tmp_path, capsys):
    # It printed "spcopyro features IMAGES --out Ft.csv --head HEAD" whatever --weights it was
    # trained on: run as printed, the head read ImageNet features; and `features` had no --seed,
    # so a head trained on `--weights random --seed 3` could not be run on its backbone at all.
    import argparse

    from spcopyro.features.cli import add_parser

    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command", required=True))
    rng = np.random.default_rng(1)
    for i in range(2):
        assert cv2.imwrite(str(tmp_path / f"{i}.png"), rng.integers(0, 256, (9, 9, 3), np.uint8))
    (tmp_path / "labels.csv").write_text("0.png,kitchen\n1.png,bedroom\n")
    head = tmp_path / "my head.pt"
    argv = ["features-head", tmp_path / "labels.csv", "--out", head, "--weights", "random"]
    args = parser.parse_args([str(a) for a in [*argv, "--seed", 3, "--epochs", 1]])
    assert args.func(args) == 0
    hint = capsys.readouterr().out.rsplit("use it with: ", 1)[1].rstrip(")\n")
    assert (
        hint == f"spcopyro features IMAGES --out Ft.csv --head '{head}' --weights random --seed 3"
    )
    out = tmp_path / "Ft.csv"
    words = shlex.split(hint)[1:]  # as printed, IMAGES and Ft.csv filled in
    words[words.index("IMAGES")], words[words.index("Ft.csv")] = str(tmp_path), str(out)
    args = parser.parse_args(words)
    assert args.seed == 3 and args.func(args) == 0
    trained = PlaceClassifier.load("random", seed=3)
    load_head(trained, head)
    expected = extract_features(trained, list_images(tmp_path), progress=False)
    assert np.array_equal(np.loadtxt(out, delimiter=",", ndmin=2), expected)


def test_training_a_head_shows_a_progress_bar(model, capsys):
    # features-head trained for minutes (fc6 tuned: about 4 s an epoch on 132 images) after the
    # activations' bar had finished, with nothing on the screen.
    from spcopyro.features.head import train_head

    model.replace_head(2)
    inputs = torch.randn(4, 4096, generator=torch.Generator().manual_seed(0))
    labels = torch.tensor([0, 1, 0, 1])
    train_head(model, inputs, labels, mode="labels", epochs=3, progress=True)
    err = capsys.readouterr().err
    assert "training head" in err and "3/3" in err
    train_head(model, inputs, labels, mode="labels", epochs=3, progress=False)
    assert "training head" not in capsys.readouterr().err


def test_options_are_checked_when_parsed(capsys):
    # --max-images-per-trial -2 silently trained on all but the last two images of each trial
    # (a negative slice); --lr -1, --batch 0, --seed -1 failed later with messages naming no
    # option ("Invalid learning rate: -1.0", "batch_size must be >= 1").
    import argparse

    from spcopyro.features.cli import add_parser
    from spcopyro.features.distill import distillation_report

    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command", required=True))
    for command, option, value in (
        ("features-head", "--max-images-per-trial", "-2"),
        ("features-head", "--max-images-per-trial", "0"),
        ("features-head", "--lr", "-1"),
        ("features-head", "--lr", "nan"),
        ("features-head", "--epochs", "-1"),
        ("features-head", "--seed", "-1"),
        ("features-head", "--batch", "0"),
        ("features", "--batch", "0"),
        ("features", "--seed", str(2**63)),
    ):
        with pytest.raises(SystemExit):
            parser.parse_args([command, "source", "--out", "x", option, value])
        assert f"argument {option}:" in capsys.readouterr().err
    with pytest.raises(ValueError, match="max_images_per_trial must be >= 1"):
        distillation_report(None, max_images_per_trial=-2)  # type: ignore[arg-type]


def test_frames_numbered_without_zero_padding_are_named_in_a_warning(tmp_path, caplog):
    # frame_1, frame_2, frame_10 gave rows in the order 1, 10, 2 without a word: row 2 held
    # frame 10's features, misaligned with the poses listed in capture order.
    for i in (1, 2, 10):
        assert cv2.imwrite(str(tmp_path / f"frame_{i}.png"), np.zeros((4, 4, 3), np.uint8))
    caplog.set_level("WARNING", logger="spcopyro")
    paths = list_images(tmp_path)
    assert [p.name for p in paths] == ["frame_1.png", "frame_10.png", "frame_2.png"]
    assert "without zero padding" in caplog.text and "row 2 is frame_10.png" in caplog.text
    caplog.clear()
    for i in (1, 2, 10):
        (tmp_path / f"frame_{i}.png").rename(tmp_path / f"frame_{i:05d}.png")
    assert cv2.imwrite(str(tmp_path / "Z.png"), np.zeros((4, 4, 3), np.uint8))
    list_images(tmp_path)
    assert caplog.text == ""


def test_a_broken_link_is_an_unreadable_image_not_a_silently_missing_row(tmp_path):
    # list_images kept only is_file() entries: a dangling 00001.jpg link was left out of a flat
    # folder without a word (one row fewer), while load_house counts it among a trial's images.
    assert cv2.imwrite(str(tmp_path / "00000.png"), np.zeros((4, 4, 3), np.uint8))
    (tmp_path / "00001.jpg").symlink_to(tmp_path / "gone.jpg")
    (tmp_path / "folder.jpg").mkdir()  # a folder is no image
    paths = list_images(tmp_path)
    assert [p.name for p in paths] == ["00000.png", "00001.jpg"]
    from spcopyro.features.images import UnreadableImagesError

    with pytest.raises(UnreadableImagesError, match=r"00001.jpg: a link to .*gone.jpg"):
        extract_features(PlaceClassifier.load("random"), paths, progress=False)
    with pytest.raises(NotADirectoryError, match=r"00000.png: a file, not a folder"):
        list_images(tmp_path / "00000.png")


def test_img_folders_and_pose_files_of_a_house_must_name_the_same_trials(tmp_path):
    # An img_7/ with no pose_7.csv added its images as rows (Ft.csv then one trial longer than
    # Xtx.csv, found only by fit); a pose_2.csv without img_2/ left that trial's rows out.
    for k in (0, 1):
        (tmp_path / f"img_{k}").mkdir()
        assert cv2.imwrite(str(tmp_path / f"img_{k}" / "00001.png"), np.zeros((4, 4, 3), np.uint8))
        (tmp_path / f"pose_{k}.csv").write_text("0,0,0,1\n")
    assert len(list_images(tmp_path)) == 2
    (tmp_path / "img_7").mkdir()
    assert cv2.imwrite(str(tmp_path / "img_7" / "00001.png"), np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(ValueError, match=r"img_7/ has no pose_7.csv \(the trials are 0, 1,"):
        list_images(tmp_path)
    (tmp_path / "img_7" / "00001.png").unlink()
    (tmp_path / "img_7").rmdir()
    (tmp_path / "pose_2.csv").write_text("0,0,0,1\n1,0,0,1\n")
    with pytest.raises(ValueError, match=r"pose_2.csv lists 2 poses but there is no img_2/"):
        list_images(tmp_path)


def test_distillation_without_paired_images_says_which_image_is_missing(tmp_path):
    # load_house only logs why it paired no images with Ft.csv's rows; the error then said
    # "no camera images (img_K/ folders)" of a house that has them, one image short.
    from types import SimpleNamespace

    from spcopyro.features.distill import distillation_report

    (tmp_path / "img_0").mkdir()
    for name in ("00001.png", "00003.png"):
        assert cv2.imwrite(str(tmp_path / "img_0" / name), np.zeros((4, 4, 3), np.uint8))
    (tmp_path / "pose_0.csv").write_text("0,0,0,1\n" * 3)
    house = SimpleNamespace(
        name="h", source=tmp_path, observations=SimpleNamespace(image_paths=None)
    )
    with pytest.raises(ValueError, match=r"img_0: 2 images but pose_0.csv has 3 .*00002.png"):
        distillation_report(house)  # type: ignore[arg-type]


def test_an_out_that_cannot_be_written_is_refused_before_any_work(images_dir, tmp_path):
    # --out FOLDER said "already exists; pass --overwrite", and with --overwrite ran every image
    # and then failed with "[Errno 21] Is a directory"; features-head trained first, then
    # crashed in torch.save with a traceback. The ImageNet weights are missing here: the
    # errors below come before they are looked for.
    import argparse

    from spcopyro.features.cli import add_parser
    from spcopyro.features.extract import extract_to_csv, write_features_csv

    (tmp_path / "a_file").write_text("")
    for out, error in (
        (tmp_path, r"a folder, not a file"),
        (tmp_path / "a_file" / "Ft.csv", r"a_file is a file, not a folder"),
    ):
        with pytest.raises(OSError, match=error):
            extract_to_csv(images_dir, out, overwrite=True)
        with pytest.raises(OSError, match=error):
            write_features_csv(out, np.ones((1, 2)), overwrite=True)
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command", required=True))
    (tmp_path / "labels.csv").write_text("no_such.png,kitchen\n")
    args = parser.parse_args(
        ["features-head", str(tmp_path / "labels.csv"), "--out", str(tmp_path), "--overwrite"]
    )
    with pytest.raises(IsADirectoryError, match="a folder, not a file"):
        args.func(args)
    out = write_features_csv(tmp_path / "new" / "Ft.csv", np.ones((1, 2)))
    assert out.read_text() == "1.0,1.0\n" and [p.name for p in out.parent.iterdir()] == ["Ft.csv"]


def test_image_lists_name_one_entry_over_the_limit_instead_of_counting_it(tmp_path):
    """The missing images of a labels file (5 named) and the unreadable images (20 named) ended
    "; ... and 1 more" where one over the limit: a phrase as long as the entry it hid
    (messages.shown_count, as listed does since 43376ef)."""
    from spcopyro.features.images import UnreadableImagesError, read_labelled_images

    labels = tmp_path / "labels.csv"
    gone = [f"images/gone{i}.png" for i in range(6)]
    labels.write_text(
        "".join(f"{g},{'kitchen' if i % 2 else 'bedroom'}\n" for i, g in enumerate(gone))
    )
    with pytest.raises(FileNotFoundError) as info:
        read_labelled_images(labels)
    message = str(info.value)
    assert "6 of 6 image(s) not found (line 1: " in message and "... and" not in message
    assert f"line 6: {tmp_path / 'images' / 'gone5.png'}); an IMAGE" in message
    labels.write_text(labels.read_text() + "images/gone6.png,kitchen\n")
    with pytest.raises(FileNotFoundError, match=r"gone4\.png; \.\.\. and 2 more\); an IMAGE"):
        read_labelled_images(labels)
    failures = [(Path(f"{i:05d}.jpg"), "not an image") for i in range(21)]
    message = str(UnreadableImagesError(failures, 30))
    assert message.endswith("00020.jpg: not an image") and "... and" not in message
    message = str(UnreadableImagesError([*failures, (Path("x.jpg"), "cut")], 30))
    assert message.endswith("00019.jpg: not an image; ... and 2 more")


def test_a_labels_file_names_its_missing_images_and_needs_two_places(tmp_path, images_dir):
    # A missing image was reported as "a_color.jpg: image file not found", with no word of the
    # labels file, its line, or that IMAGE is relative to the labels file's folder; labels of
    # one place trained a 1-class head whose every feature is 1.0.
    import argparse

    from spcopyro.features.cli import add_parser
    from spcopyro.features.images import read_labelled_images

    labels = tmp_path / "labels.csv"
    labels.write_text("images/00000.png,kitchen\n# note\nimages/gone.png,bedroom\n")
    with pytest.raises(FileNotFoundError) as info:
        read_labelled_images(labels)
    message = str(info.value)
    assert "labels.csv: 1 of 2 image(s) not found (line 3: " in message
    assert f"relative to the labels file's folder, {tmp_path.resolve()}" in message
    labels.write_text("images/00000.png,kitchen\nimages/00001.png,kitchen\n")
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["features-head", str(labels), "--out", str(tmp_path / "h.pt")])
    with pytest.raises(ValueError, match="every image is labelled 'kitchen'"):
        args.func(args)


def test_distillation_leaves_out_all_zero_rows_and_says_which(tmp_path, pristine, caplog):
    # An all-zero Ft.csv row (load_house warns of it) stopped the distillation after all the
    # activations with "target histogram 14 sums to 0", an index into the training subset.
    from types import SimpleNamespace

    from spcopyro.features.distill import distillation_report

    paths = []
    for i in range(4):
        paths.append(tmp_path / f"{i}.png")
        assert cv2.imwrite(str(paths[-1]), np.full((8, 8, 3), 60 * i, np.uint8))
    features = np.array([[0.5, 0.5], [0.0, 0.0], [0.9, 0.1], [0.2, 0.8]])
    obs = SimpleNamespace(
        image_paths=tuple(paths),
        image_trial=np.array([0, 0, 1, 1]),
        image_features=features,
        num_feature_classes=2,
    )
    house = SimpleNamespace(name="h", source=tmp_path, observations=obs)
    caplog.set_level("WARNING", logger="spcopyro")
    report = distillation_report(house, model=copy.deepcopy(pristine), epochs=1, progress=False)
    assert "1 image(s) left out of the distillation" in caplog.text and "(lines 2)" in caplog.text
    assert (report.num_train, report.num_test) == (1, 2)
    obs.image_features = np.array([[0.0, 0.0], [0.0, 0.0], [0.9, 0.1], [0.2, 0.8]])
    with pytest.raises(ValueError, match="every training image's Ft.csv row is all zero"):
        distillation_report(house, model=copy.deepcopy(pristine), epochs=1, progress=False)


def test_a_failed_download_names_the_url_and_what_else_to_do(monkeypatch, capsys):
    # --download without internet ended with "error: <urlopen error [Errno -2] Name or service
    # not known>", naming neither the file nor another way to get it; and the 233 MB download
    # had its progress bar switched off.
    import urllib.error

    from spcopyro.features.backbone import WeightsNotFoundError, torchvision_cache_file

    seen = {}

    def offline(url, dst, hash_prefix=None, progress=True):
        seen["progress"] = progress
        raise urllib.error.URLError("[Errno -2] Name or service not known")

    monkeypatch.setattr(torch.hub, "download_url_to_file", offline)
    monkeypatch.delenv("CI", raising=False)
    with pytest.raises(WeightsNotFoundError) as info:
        load_alexnet("imagenet", download=True)
    message = str(info.value)
    assert message.startswith("downloading https://download.pytorch.org/models/alexnet-owt")
    assert str(torchvision_cache_file()) in message and "--weights PATH" in message
    assert seen["progress"] is True


def test_trial_folders_are_named_with_ascii_digits_as_load_house_reads_them(tmp_path):
    # r"img_(\d+)" also took "img_٣" (Arabic-Indic three) as trial 3, which load_house (r"[0-9]")
    # does not: its images became rows that no pose or Xtx.csv line belongs to.
    (tmp_path / "img_0").mkdir()
    (tmp_path / "img_\u0663").mkdir()
    for folder in ("img_0", "img_\u0663"):
        assert cv2.imwrite(str(tmp_path / folder / "00001.png"), np.zeros((4, 4, 3), np.uint8))
    assert [p.parent.name for p in list_images(tmp_path)] == ["img_0"]


def test_two_folders_of_one_trial_are_refused(tmp_path):
    # img_1/ and img_01/ both went in as trial 1 (rows twice), where load_house refuses them.
    for folder in ("img_1", "img_01"):
        (tmp_path / folder).mkdir()
        assert cv2.imwrite(str(tmp_path / folder / "00001.png"), np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(ValueError, match=r"img_01/ and img_1/ are both trial 1"):
        list_images(tmp_path)


def test_distillation_options_with_a_labels_file_are_refused(tmp_path):
    # --held-out-trial 1 with a labels file was silently ignored: no trial was held out.
    import argparse

    from spcopyro.features.cli import add_parser

    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command", required=True))
    (tmp_path / "labels.csv").write_text("a.png,kitchen\nb.png,bedroom\n")
    args = parser.parse_args(
        ["features-head", str(tmp_path / "labels.csv"), "--out", str(tmp_path / "h.pt")]
        + ["--held-out-trial", "1", "--max-images-per-trial", "3"]
    )
    with pytest.raises(ValueError, match="--held-out-trial, --max-images-per-trial choose"):
        args.func(args)


def test_a_missing_source_is_not_only_called_a_labels_file(tmp_path):
    # features-head room1dkX (a typo in a house's name) said "room1dkX: labels file not found".
    from spcopyro.features.images import read_labelled_images

    with pytest.raises(FileNotFoundError, match="room1dkX: no such labels file .nor house folder"):
        read_labelled_images(tmp_path / "room1dkX")


def test_features_seed_without_random_weights_is_refused(tmp_path):
    import argparse

    from spcopyro.features.cli import add_parser

    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["features", str(tmp_path), "--out", "x.csv", "--seed", "3"])
    with pytest.raises(ValueError, match="--seed 3: the seed of --weights random, not of imagenet"):
        args.func(args)


def test_a_labels_file_written_on_windows_finds_its_images(tmp_path, images_dir):
    """`images\\00000.png` (a labels file written on Windows) was one file name on Linux: every
    image 'not found'. A backslash reads as a slash where only that names a file."""
    from spcopyro.features.images import read_labelled_images

    labels = tmp_path / "labels.csv"
    labels.write_text("images\\00000.png,kitchen\nimages\\00001.png,bedroom\n")
    paths, names = read_labelled_images(labels)
    assert paths == [tmp_path / "images" / "00000.png", tmp_path / "images" / "00001.png"]
    assert names == ["kitchen", "bedroom"]
    labels.write_text("images\\gone.png,kitchen\nimages\\00001.png,bedroom\n")
    with pytest.raises(FileNotFoundError, match="1 of 2 image"):
        read_labelled_images(labels)


def test_an_image_of_one_pixel_high_is_refused_not_resized_to_gigabytes(tmp_path):
    """A 100000 x 1 image was resized to 25.6 million x 256 pixels (20 GB) before its central
    crop; an image more than MAX_ASPECT_RATIO times as wide as high is refused, naming its file
    and size, beside the other unreadable images."""
    from spcopyro.features.images import MAX_ASPECT_RATIO, UnreadableImagesError

    assert cv2.imwrite(
        str(tmp_path / "00000.png"), np.zeros((20, 20 * MAX_ASPECT_RATIO, 3), np.uint8)
    )
    assert cv2.imwrite(str(tmp_path / "00001.png"), np.zeros((1000, 1, 3), np.uint8))
    assert cv2.imwrite(str(tmp_path / "00002.png"), np.zeros((1, 1000, 3), np.uint8))
    with pytest.raises(UnreadableImagesError) as error:
        extract_features(PlaceClassifier.load("random"), list_images(tmp_path), progress=False)
    assert [(p.name, r.split(",")[0]) for p, r in error.value.failures] == [
        ("00001.png", "a 1 x 1000 image (width x height)"),
        ("00002.png", "a 1000 x 1 image (width x height)"),
    ]
    assert "more than 32 times as wide as high: not a camera frame" in str(error.value)
