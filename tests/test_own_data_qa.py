"""A roboticist's own house (not the public dataset's): what goes wrong between their images,
``spcopyro features`` and a fit, and between their words and ``where``.

The grid is a 2 x 3 room of free cells at 1 m (origin (0, 0)), walled by nothing: every
observation inside it lands on a free cell.
"""

from __future__ import annotations

import json
import logging
import unicodedata

import numpy as np
import pytest

from spcopyro.data import (
    DataFormatError,
    House,
    Observations,
    cell_counts,
    load_house,
    save_house,
    tokenize,
)
from spcopyro.data.text import format_characters, unsegmented
from spcopyro.maps import FREE, OccupancyGrid


def _grid() -> OccupancyGrid:
    return OccupancyGrid(
        occupancy=np.full((2, 3), FREE, dtype=np.int8), resolution=1.0, origin=(0.0, 0.0, 0.0)
    )


def _observations(features: np.ndarray, utterances: list[tuple[str, ...]]) -> Observations:
    num_images, num_words = features.shape[0], len(utterances)
    return Observations(
        image_features=features,
        image_xy=np.full((num_images, 2), 0.5),
        image_trial=np.zeros(num_images, dtype=np.int64),
        utterances=utterances,
        word_xy=np.full((num_words, 2), 1.5),
        word_trial=np.zeros(num_words, dtype=np.int64),
    )


def test_floor100_of_a_1000_class_histogram_is_not_lost_silently(tmp_path, caplog):
    """``spcopyro features`` writes 1000 ImageNet classes; a flat histogram's probabilities are
    all below 0.01, and ``floor100`` (the paper presets, the refinement's 100 draws) made every
    such row 0: the images vanished from the counts without a word."""
    flat = np.full((3, 1000), 1e-3)  # [3, 1000] each row sums to 1, every entry < 0.01
    peaked = np.zeros((1, 1000))
    peaked[0, 7] = 1.0
    obs = _observations(np.concatenate([flat, peaked]), [("kitchen",)])
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        counts = cell_counts(_grid(), obs, feature_scaling="floor100")
    assert counts.image_counts.sum() == 100.0  # only the peaked image is left
    lost = [r.getMessage() for r in caplog.records if "carry no information" in r.getMessage()]
    assert len(lost) == 1, caplog.text
    assert "3 of 4 image(s)" in lost[0] and "images 0, 1, 2" in lost[0]
    assert "'probability'" in lost[0]
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        cell_counts(_grid(), obs, feature_scaling="probability")
        cell_counts(_grid(), obs, feature_scaling="floor100", footprint_radius=1.0, source=tmp_path)
    said = [r.getMessage() for r in caplog.records if "carry no information" in r.getMessage()]
    assert len(said) == 1  # not with probabilities; once with a footprint
    assert f"lines 1, 2, 3 of {tmp_path / 'Ft.csv'}" in said[0]  # a house folder's file


def test_one_word_in_two_unicode_forms_is_one_vocabulary_word():
    """A Japanese IME types full-width ``ＴＶ``, another recogniser ``TV``; text from macOS holds
    decomposed kana. ``where`` read them as one word, but the data's tokenizer only lower-cased,
    so the fit counted two words (``tv``, ``ｔｖ``) and ``where tv`` found only the first."""
    decomposed = unicodedata.normalize("NFD", "ダイニング")
    texts = ("TV", "ＴＶ", "ダイニング", decomposed, "STRASSE", "Straße")
    utterances = [tokenize(text) for text in texts]
    assert utterances == [("tv",)] * 2 + [("ダイニング",)] * 2 + [("strasse",)] * 2
    obs = _observations(np.full((1, 3), 1 / 3), utterances)
    assert obs.vocabulary == ("tv", "ダイニング", "strasse")
    counts = cell_counts(_grid(), obs)
    assert counts.word_counts.sum(axis=0).tolist() == [2.0, 2.0, 2.0]


def test_features_reads_a_pose_file_with_a_header_as_load_house_does(tmp_path):
    """``spcopyro features HOUSE`` counted a pose file's non-blank lines: a header line
    ``x,y,qz,qw`` was one more pose, reported as a missing image ("missing: 00002.png") that the
    user then looked for; it is the header, named with its line as load_house names it."""
    cv2 = pytest.importorskip("cv2")
    from spcopyro.features.images import list_images

    (tmp_path / "img_0").mkdir()
    for number in range(2):
        cv2.imwrite(str(tmp_path / "img_0" / f"{number:05d}.png"), np.zeros((8, 8, 3), np.uint8))
    poses = tmp_path / "pose_0.csv"
    poses.write_text("x,y,qz,qw\n0.5,0.5,0,1\n1.5,0.5,0,1\n")
    said = r"pose_0\.csv, line 1, column 1: not a number \(a header line\? .*\): 'x'"
    with pytest.raises(DataFormatError, match=said):
        list_images(tmp_path)
    poses.write_text("0.5,0.5,0\n1.5,0.5,0\n")  # x, y, yaw: a pose of another form
    with pytest.raises(DataFormatError, match=r"expected 4 \(x, y, qz, qw\)"):
        list_images(tmp_path)
    poses.write_text("0.5,0.5,0,1\r\n1.5,0.5,0,1\r\n")
    assert [p.name for p in list_images(tmp_path)] == ["00000.png", "00001.png"]


def test_a_labels_file_that_spells_one_place_two_ways_is_refused(tmp_path):
    """``features-head labels.csv`` trained ``Kitchen`` and ``kitchen`` (or ``living room`` and
    ``living  room``) as two places: the head split the kitchen's images between two classes,
    with no word of it."""
    pytest.importorskip("torch")
    from spcopyro.features.head import encode_labels
    from spcopyro.features.images import read_labelled_images

    for number in range(4):
        (tmp_path / f"{number}.jpg").write_bytes(b"")
    labels = tmp_path / "labels.csv"
    labels.write_text("0.jpg,kitchen\n1.jpg,living room\n# a comment\n2.jpg,Kitchen\n3.jpg,bed\n")
    with pytest.raises(ValueError, match=r"labels\.csv, line 4: place 'Kitchen' is written "
                       r"'kitchen' on line 1: they differ only in case"):  # fmt: skip
        read_labelled_images(labels)
    with pytest.raises(ValueError, match=r"'living room' \(image 0\) and 'living  room' \(image"):
        encode_labels(["living room", "bed", "living  room"])
    with pytest.raises(ValueError, match=r"'ＴＶ' \(image 0\) and 'TV' \(image 1\)"):
        encode_labels(["ＴＶ", "TV"])
    classes, _ = encode_labels(["kitchen", "bed", "kitchen"])
    assert classes == ("bed", "kitchen")


def _saved_house(root):
    """A two-image, three-utterance house written in the dataset layout; its room folder."""
    obs = Observations(
        image_features=[[0.5, 0.5], [0.25, 0.75]],
        image_xy=[[0.5, 0.5], [2.5, 1.5]],
        image_trial=[0, 1],
        utterances=[("here", "is", "the", "kitchen"), ("bed",), ("kitchen",)],
        word_xy=[[0.5, 0.5], [2.5, 1.5], [1.5, 0.5]],
        word_trial=[0, 1, 1],
    )
    return save_house(House(name="home", grid=_grid(), observations=obs), root)


def test_old_mac_line_ends_read_as_lines(tmp_path):
    """Excel's "CSV (Macintosh)" ends lines with CR alone: Xtx.csv was one line,
    '0.5\\r2.5', refused as not a number, and a word file was one utterance."""
    room = _saved_house(tmp_path)
    expected = load_house(room).observations
    for name in ("Xtx.csv", "Ft.csv", "pose_1.csv", "word_1.csv", "StXtx.csv"):
        path = room / name
        path.write_bytes(path.read_bytes().replace(b"\n", b"\r"))
    loaded = load_house(room).observations
    np.testing.assert_array_equal(loaded.image_xy, expected.image_xy)
    np.testing.assert_array_equal(loaded.image_features, expected.image_features)
    assert loaded.utterances == expected.utterances
    np.testing.assert_array_equal(loaded.word_trial, expected.word_trial)


def test_utf16_and_a_comma_in_a_word_file_say_what_is_wrong(tmp_path):
    """Excel's "Unicode text" is UTF-16 (was: 'not UTF-8 text (invalid start byte): b"\\xff"');
    a comma in a word file's sentence splits St.csv's entry in two (was: only the counts)."""
    room = _saved_house(tmp_path)
    (room / "St.csv").write_bytes("here is the kitchen,bed,kitchen".encode("utf-16"))
    with pytest.raises(DataFormatError, match=r"St\.csv: UTF-16 text .* save it as UTF-8"):
        load_house(room)
    (room / "St.csv").write_text("Here, the kitchen,bed,kitchen")
    with pytest.raises(DataFormatError, match=r"StXtx\.csv: holds 3 values but St\.csv holds 4 "
                       r"entries \(St\.csv separates utterances with commas"):  # fmt: skip
        load_house(room)
    for name in ("StXtx.csv", "StXty.csv"):  # the positions made for St.csv's entries
        (room / name).write_text((room / name).read_text() + "0.5\n")
    (room / "word_0.csv").write_text("Here, the kitchen\n")
    with pytest.raises(
        DataFormatError,
        match=r"holds 4 utterances but the word files hold 3 .*; word_0\.csv line 1 holds a comma",
    ):
        load_house(room)


def test_a_house_without_ft_csv_says_how_to_make_it(tmp_path):
    """A house of camera images and words whose Ft.csv is not made yet (fit before features),
    or one with words only: "Ft.csv: required file not found" said neither what it holds nor
    how to make it."""
    room = _saved_house(tmp_path)
    (room / "Ft.csv").unlink()
    with pytest.raises(FileNotFoundError, match=r"Xtx\.csv, Xty\.csv, pose_0\.csv, pose_1\.csv "
                       "give image positions but no features: spcopyro features"):  # fmt: skip
        load_house(room)
    for name in ("Xty.csv", "pose_0.csv", "pose_1.csv"):
        (room / name).rename(tmp_path / name)
    with pytest.raises(FileNotFoundError, match=r"\(the image features; Xtx\.csv gives image "):
        load_house(room)  # one file: 'gives'
    for name in ("Xty.csv", "pose_0.csv", "pose_1.csv"):
        (tmp_path / name).rename(room / name)
    (room / "img_0").mkdir()
    (room / "img_0" / "00000.jpg").write_bytes(b"")
    with pytest.raises(FileNotFoundError, match=rf"spcopyro features {room} --out {room}/Ft"):
        load_house(room)
    (room / "St.csv").unlink()
    (room / "Ft.csv").write_text("0.5,0.5\n0.25,0.75\n")
    with pytest.raises(FileNotFoundError, match=r"St\.csv: required file not found \(the words "
                       r"heard, .*; StXtx\.csv, StXty\.csv, word_0\.csv, word_1\.csv are here "
                       "without it"):  # fmt: skip
        load_house(room)


def test_a_house_of_images_only_loads_and_fits(tmp_path, capsys):
    """A house of images only (no word files at all: a robot that has heard nothing yet) was
    refused ('spcopyro cannot fit it, since the words heard name its places'), and had no way
    in; it now loads with no utterances (warned, naming the folder) and fits from its images."""
    from spcopyro.cli.main import main

    room = _saved_house(tmp_path)
    for name in ("St.csv", "StXtx.csv", "StXty.csv", "word_0.csv", "word_1.csv"):
        (room / name).unlink()
    assert load_house(room).observations.num_utterances == 0
    assert main(["fit", str(room), "--out", str(tmp_path / "fit"), "--sweeps", "2"]) == 0
    printed = capsys.readouterr()
    assert f"{room}: no words" in printed.err and "fitted on its images alone" in printed.err
    # the summary says so, as it does of a house of words only's images
    assert "utterances       none (a house of images only) in 2 trials" in printed.out


def test_a_house_of_words_only_loads_saves_and_fits(tmp_path, caplog, capsys):
    """A robot without a camera: no Ft.csv, Xtx.csv, Xty.csv, pose_K.csv. It was refused ("a
    house needs images as well as words"), though the words alone place the concepts; now its
    images are [0, 1], warned of, its trials are the word files', and it saves and fits."""
    from spcopyro.cli.main import main
    from spcopyro.synthetic import HouseSpec, write_synthetic

    room = _saved_house(tmp_path / "a")
    for name in ("Ft.csv", "Xtx.csv", "Xty.csv", "pose_0.csv", "pose_1.csv"):
        (room / name).unlink()
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        house = load_house(room)
    assert "no images (no Ft.csv" in caplog.text and "fitted on its words alone" in caplog.text
    obs = house.observations
    assert obs.num_images == 0 and obs.image_features.shape == (0, 1) and obs.image_yaw is None
    assert obs.trials == (0, 1) and obs.word_trial.tolist() == [0, 1, 1]
    again = save_house(house, tmp_path / "b")
    assert not (again / "Ft.csv").exists() and not (again / "pose_0.csv").exists()
    assert load_house(again).observations.word_trial.tolist() == [0, 1, 1]

    data = write_synthetic(tmp_path / "c", seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3))
    for path in [*data.glob("pose_*.csv"), data / "Ft.csv", data / "Xtx.csv", data / "Xty.csv"]:
        path.unlink()
    out = tmp_path / "fit"
    assert main(["fit", str(data), "--out", str(out), "--sweeps", "30", "--no-figures"]) == 0
    printed = capsys.readouterr().out
    assert "images           none (a house of words only) in 3 trials" in printed
    (model,) = [line for line in printed.splitlines() if line.startswith("model ")]
    # the model in effect: it printed use_images=True beside "(use_images: no images here)"
    shown = model.split(" (no images here")[0]
    assert shown.endswith(", chi 1, words only") and "use_images" not in shown, model
    assert model.endswith("(no images here: use_images=True, as config.json records it, has none "
                          "to use)")  # fmt: skip
    assert json.loads((out / "config.json").read_text())["model"]["use_images"] is True
    assert (out / "labels.npy").is_file()


def test_a_one_column_ft_csv_is_said_to_carry_nothing(tmp_path, caplog):
    """A class id per image written as Ft.csv (``3``, ``1``, ...) loaded and fitted without a
    word: over one class every image's histogram is the same, so the images said nothing."""
    room = _saved_house(tmp_path)
    (room / "Ft.csv").write_text("3\n1\n")
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        assert load_house(room).observations.num_feature_classes == 1
    assert "Ft.csv: one column" in caplog.text and "carry no information" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        load_house(_saved_house(tmp_path / "two"))
    assert "one column" not in caplog.text


def test_invisible_characters_at_a_word_s_ends_are_not_part_of_it():
    """St.csv joined from files that each began with a byte-order mark, or text pasted with a
    zero-width space: ``\\ufeffkitchen`` was a word of its own beside ``kitchen``, and
    ``where kitchen`` found only one of them."""
    texts = ("kitchen", "\ufeffkitchen", "kitchen\u200b", "\u200bthe kitchen\u200d.")
    assert [tokenize(t) for t in texts] == [("kitchen",)] * 3 + [("the", "kitchen")]
    assert tokenize("living\u200broom") == ("living\u200broom",)  # inside a word: kept
    assert tokenize("\u200b \ufeff") == ()


def test_invisible_characters_inside_a_word_are_warned_of(tmp_path, caplog):
    """'kit\\u200bchen' (a zero-width space inside) is a word apart from 'kitchen' that prints
    the same: it was read without a word said. Kept (a Persian zero-width non-joiner spells its
    word), but named with its file, line, repr and code point."""
    assert format_characters("kit\u200bchen\u200b") == ("U+200B ZERO WIDTH SPACE",)
    assert format_characters("re\xadfrig\u200derator") == (
        "U+00AD SOFT HYPHEN", "U+200D ZERO WIDTH JOINER",
    )  # fmt: skip
    assert format_characters("kitchen") == () == format_characters("ダイニングキッチン")
    room = _saved_house(tmp_path)
    (room / "St.csv").write_text("here is the kitchen,b\ufeffed,kit\u200bchen kit\u200bchen")
    (room / "word_0.csv").write_text("here is the kitchen\n")
    (room / "word_1.csv").write_text("b\ufeffed\nkit\u200bchen kit\u200bchen\n")
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        house = load_house(room)
    assert house.observations.utterances[2] == ("kit\u200bchen",) * 2  # kept, not stripped
    said = [r.getMessage() for r in caplog.records if "format characters" in r.getMessage()]
    assert said == [
        f"{room / 'St.csv'}, line 1: 2 word(s) hold invisible format characters (Unicode "
        "category Cf), each read as a word apart from its letters without them: 'b\\ufeffed' "
        "(utterance 2: U+FEFF ZERO WIDTH NO-BREAK SPACE), 'kit\\u200bchen' (utterance 3: U+200B "
        "ZERO WIDTH SPACE) (kept: remove them where the language does not need them, as "
        "Persian needs its zero-width non-joiner)"
    ]
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        load_house(_saved_house(tmp_path / "clean"))
    assert "format characters" not in caplog.text


@pytest.mark.parametrize(
    ("line", "said"),
    [
        ("5.0e-01 2.5e-01", "numbers separated by spaces"),  # np.savetxt's default delimiter
        ("0.5\t0.25", "numbers separated by tabs"),
        ("0.5;0.25", "numbers separated by semicolons"),
        ("0,5;0,25", "semicolons and decimal commas"),
    ],
)
def test_numbers_separated_otherwise_than_by_commas_say_so(tmp_path, line, said):
    """np.savetxt writes spaces unless told otherwise, spreadsheets tabs or semicolons (and
    decimal commas): the error named the line as 'not a number' or 'row has 1 values'."""
    room = _saved_house(tmp_path)
    (room / "Ft.csv").write_text(f"{line}\n0.25,0.75\n")
    with pytest.raises(DataFormatError, match=rf"Ft\.csv, line 1: .*\({said}"):
        load_house(room)
    (room / "Ft.csv").write_text("0.5,0.25\n0.5,x\n")
    with pytest.raises(DataFormatError, match=r"line 2, column 2: not a number: 'x'$"):
        load_house(room)


def test_a_position_written_with_a_decimal_comma_says_so(tmp_path):
    """A one-column file saved by a spreadsheet in a language that writes decimal commas
    (``0,5``): the error said 'row has 2 values, expected 1' and nothing of the comma."""
    room = _saved_house(tmp_path)
    (room / "StXtx.csv").write_text("0,5\n2,5\n1,5\n")
    with pytest.raises(DataFormatError) as error:
        load_house(room)
    assert str(error.value) == (
        f"{room / 'StXtx.csv'}, line 1: row has 2 values, expected 1 (a decimal comma, as a "
        "spreadsheet in some languages writes it: these files write decimals with a point): '0,5'"
    )
    (room / "StXtx.csv").write_text("0.5\n2.5\n1.5,2\n")  # two numbers: no such hint
    with pytest.raises(DataFormatError, match=r"line 3: row has 2 values, expected 1: '1.5,2'$"):
        load_house(room)


@pytest.mark.parametrize(
    ("text", "line", "value"),
    [("0,25\n0,75\n", 1, "0,25"), ("1,0\n0,5\n", 2, "0,5"), ("1,0\n0,05\n", 2, "0,05")],
)
def test_a_one_column_ft_written_with_decimal_commas_is_refused(tmp_path, text, line, value):
    """A one-column Ft.csv saved with decimal commas (``0,25``) read as two columns, 0 and 25:
    a two-class histogram the file never held, fitted without a word."""
    room = _saved_house(tmp_path)
    (room / "Ft.csv").write_text(text)
    with pytest.raises(DataFormatError) as error:
        load_house(room)
    assert str(error.value).startswith(f"{room / 'Ft.csv'}, line {line}: two whole numbers a ")
    assert str(error.value).endswith(f"0.0,25.0 to say so: {value!r}")
    (room / "Ft.csv").write_text("0,25\n1\n")  # then a line of one number: the row's length
    with pytest.raises(DataFormatError, match=r"line 2: row has 1 values, expected 2 \(a decimal"):
        load_house(room)
    for counts in ("0,1\n1,0\n", "3,25\n0,1\n", "0.0,25.0\n0.0,75.0\n"):  # two columns
        (room / "Ft.csv").write_text(counts)
        assert load_house(room).observations.image_features.shape == (2, 2)


def test_japanese_written_without_spaces_is_warned_of(tmp_path, caplog):
    """Japanese as it is written, without spaces: a sentence became one word, heard nowhere else
    and matching no query, without a word said."""
    room = _saved_house(tmp_path)
    (room / "St.csv").write_text("ここは台所です,ダイニングキッチン,寝室 です")
    (room / "word_0.csv").write_text("ここは台所です\n")
    (room / "word_1.csv").write_text("ダイニングキッチン\n寝室 です\n")
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        house = load_house(room)
    assert house.observations.utterances[0] == ("ここは台所です",)  # read as it is, one word
    said = [r.getMessage() for r in caplog.records if "without spaces" in r.getMessage()]
    assert said == [
        f"{room / 'St.csv'}, line 1: 1 utterance(s) look like sentences written without "
        "spaces, each read as one word: utterance 1 'ここは台所です' (nothing splits such text: "
        "write it with spaces between its words, as MeCab's mecab -Owakati does)"
    ]
    caplog.clear()
    (room / "St.csv").write_text("ここ は 台所 です,ダイニングキッチン,お手洗い")  # segmented
    (room / "word_0.csv").write_text("ここ は 台所 です\n")
    (room / "word_1.csv").write_text("ダイニングキッチン\nお手洗い\n")
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        load_house(room)
    assert "without spaces" not in caplog.text


def test_unsegmented_takes_long_unspaced_words_for_sentences():
    sentences = ("ここは台所です", "这里是卫生间", "リビングルームです", "นี่คือห้องครัวครับผม")
    words = ("ダイニングキッチン", "お手洗い", "電子レンジ", "ห้องครัว", "台所です", "холодильник")
    assert [unsegmented(t) for t in sentences] == [True] * 4
    assert [unsegmented(t) for t in words] == [False] * 6
    assert not unsegmented("kitchen") and not unsegmented("ここは台所ですkitchen")


def test_macos_metadata_files_beside_the_images_are_named(tmp_path):
    """A folder copied from a Mac to a USB stick holds ``._00000.jpg`` beside ``00000.jpg``:
    features said "OpenCV cannot decode it", and in a house folder "every image after a
    missing one" for images that were extra, not missing."""
    cv2 = pytest.importorskip("cv2")
    from spcopyro.features.images import ImageReadError, list_images, read_image

    (tmp_path / "img_0").mkdir()
    for number in range(2):
        cv2.imwrite(str(tmp_path / "img_0" / f"{number:05d}.png"), np.zeros((8, 8, 3), np.uint8))
        (tmp_path / "img_0" / f"._{number:05d}.png").write_bytes(b"\x00\x05\x16\x07Mac OS X")
    with pytest.raises(ImageReadError, match=r"macOS metadata file \(AppleDouble, for 00000"):
        read_image(tmp_path / "img_0" / "._00000.png")
    (tmp_path / "pose_0.csv").write_text("0.5,0.5,0,1\n1.5,0.5,0,1\n")
    with pytest.raises(ValueError, match=r"4 images but pose_0\.csv has 2 poses: every image "
                       r"after an extra one .*2 are macOS metadata files"):  # fmt: skip
        list_images(tmp_path)


def test_distilling_a_one_trial_house_says_why_it_cannot(tmp_path):
    """A house recorded in one trial: features-head said "held-out trial 0 and training trials
    [] must be distinct trials among [0]", which asks for options, not for a second trial."""
    cv2 = pytest.importorskip("cv2")
    from spcopyro.features.distill import distillation_report

    images = []
    for number in range(2):
        images.append(tmp_path / f"{number}.png")
        cv2.imwrite(str(images[-1]), np.zeros((8, 8, 3), np.uint8))
    obs = Observations(
        image_features=[[0.5, 0.5], [0.25, 0.75]],
        image_xy=[[0.5, 0.5], [2.5, 1.5]],
        image_trial=[0, 0],
        utterances=[("kitchen",)],
        word_xy=[[0.5, 0.5]],
        word_trial=[0],
        image_paths=tuple(images),
    )
    room = save_house(House(name="home", grid=_grid(), observations=obs), tmp_path / "data")
    with pytest.raises(ValueError, match=r"one trial \(0\), and distillation trains on some"):
        distillation_report(load_house(room), weights="random")


def test_logits_in_ft_csv_are_named_as_such(tmp_path):
    """A network's logits (or log-probabilities) written as Ft.csv: "negative image feature"
    did not say what a row must hold instead."""
    room = _saved_house(tmp_path)
    (room / "Ft.csv").write_text("2.5,-1.25\n0.25,0.75\n")
    with pytest.raises(DataFormatError, match=r"line 1, column 2: negative image feature \(a "
                       r"row is a histogram .* need a softmax or exp first\): -1\.25"):  # fmt: skip
        load_house(room)


def test_utterances_given_as_strings_are_refused(tmp_path):
    """Building Observations from one's own data, ``utterances=["kitchen", "bed room"]`` (a
    string per utterance, not its tokens) made each letter a word, the space one too: the
    vocabulary was ('k', 'i', 't', 'c', 'h', 'e', 'n', 'b', 'd', ' ', ...), without a word."""
    common = dict(image_features=[[1.0]], image_xy=[[0.5, 0.5]], image_trial=[0])
    two = dict(word_xy=[[0.5, 0.5]] * 2, word_trial=[0, 0])
    with pytest.raises(ValueError, match=r"utterance 1 is a string, 'bed room': give its "
                       r"tokens, \('bed', 'room'\)"):  # fmt: skip
        Observations(**common, **two, utterances=[("kitchen",), "bed room"])
    with pytest.raises(ValueError, match=r"got the string 'ab'"):
        Observations(**common, **two, utterances="ab")
    with pytest.raises(ValueError, match=r"utterance 0 holds the token ' ': a token is non-blank"):
        Observations(**common, **two, utterances=[("kitchen", " "), ("bed",)])
    obs = Observations(**common, **two, utterances=[["kitchen"], ("bed", "room")])
    assert obs.vocabulary == ("kitchen", "bed", "room")


def test_a_labels_file_that_gives_one_image_two_places_is_refused(tmp_path):
    """``a.jpg,kitchen`` and, further down, ``./a.jpg,bedroom``: the head was trained on both
    labels for the same pixels, without a word."""
    pytest.importorskip("torch")
    from spcopyro.features.images import read_labelled_images

    for name in ("a.jpg", "b.jpg"):
        (tmp_path / name).write_bytes(b"")
    labels = tmp_path / "labels.csv"
    labels.write_text("a.jpg,kitchen\nb.jpg,bed\n./a.jpg,bed\n")
    with pytest.raises(ValueError, match=r"labels\.csv, line 3: image .*a\.jpg is labelled 'bed' "
                       r"here but 'kitchen' on line 1: one place per image"):  # fmt: skip
        read_labelled_images(labels)
    labels.write_text("a.jpg,kitchen\nb.jpg,bed\na.jpg,kitchen\n")  # the same label again: fine
    assert read_labelled_images(labels)[1] == ["kitchen", "bed", "kitchen"]


def test_a_trailing_comma_is_named(tmp_path):
    """A writer that ends each row with a comma: 'row has 5 values, expected 4' or 'not a
    number: ''' at a column past the last, without saying why."""
    room = _saved_house(tmp_path)
    pose = (room / "pose_0.csv").read_text()
    (room / "pose_0.csv").write_text(pose.replace("\n", ",\n"))
    with pytest.raises(DataFormatError, match=r"pose_0\.csv, line 1: row has 5 values, expected 4 "
                       r"\(x, y, qz, qw\) \(the line ends with a comma"):  # fmt: skip
        load_house(room)
    (room / "pose_0.csv").write_text(pose)
    (room / "Ft.csv").write_text("0.5,0.5,\n0.25,0.75,\n")
    with pytest.raises(DataFormatError, match=r"Ft\.csv, line 1: not a number \(the line ends"):
        load_house(room)
    (room / "Ft.csv").write_text("0.5,x,\n0.25,0.75,\n")  # the value that is wrong comes first
    with pytest.raises(DataFormatError, match=r"Ft\.csv, line 1, column 2: not a number: 'x'$"):
        load_house(room)


def test_timestamped_frames_in_time_order_are_not_called_unpadded(tmp_path, caplog):
    """Frames named by their time stamp, ``1699999999.123.jpg`` then ``1699999999.5.jpg``: name
    order is time order, yet the warning read the fractions as whole numbers (5 < 123) and told
    the user to rename them; an integer part of another width is still warned about."""
    cv2 = pytest.importorskip("cv2")
    from spcopyro.features.images import list_images

    for folder, names in (
        ("stamps", ("1699999999.123.jpg", "1699999999.5.jpg", "1700000000.05.jpg")),
        ("wider", ("999.5.jpg", "1000.25.jpg")),
    ):
        (tmp_path / folder).mkdir()
        for name in names:
            cv2.imwrite(str(tmp_path / folder / name), np.zeros((8, 8, 3), np.uint8))
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        list_images(tmp_path / "stamps")
    assert "zero padding" not in caplog.text
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        list_images(tmp_path / "wider")
    assert "row 1 is 1000.25.jpg, not 999.5.jpg" in caplog.text
