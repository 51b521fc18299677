"""``_util.npz.write_npz``: ``np.savez_compressed``'s file, large arrays deflated faster (issue 25).

The large-array path is taken here for arrays of 1 MiB (``LARGE`` patched), not 64 MiB."""

from __future__ import annotations

import dataclasses
import io
import zipfile
import zlib

import numpy as np
import pytest

from spcopyro._util import npz


def _npy_bytes(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=False)
    return buffer.getvalue()


def _arrays() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    frequencies = np.zeros((4000, 120), np.float32)  # [N, L] 1.9 MB: one label a cell mostly
    frequencies[np.arange(4000), rng.integers(0, 120, 4000)] = 1.0
    frequencies[::7, 3] = np.float32(0.04)
    dense = rng.dirichlet(np.ones(120), 2000).astype(np.float32)  # [N, L] 0.96 MB: level 6
    return {
        "marginals": frequencies,
        "dense": dense,
        "labels": np.repeat(rng.integers(0, 120, 3000), 100),  # [N] int64 in runs, 2.4 MB
        "pi": rng.random(120),
        "fortran": np.asfortranarray(rng.random((300, 500))),  # 1.2 MB, not C-contiguous
        "strided": rng.random((600, 600))[:, ::2],
        "name": np.array("room1ldk5"),
        "items": np.array(["bed", "sofa", "kitchen"]),
        "best_iteration": np.array(7),
        "empty": np.zeros((0, 5)),
    }


@pytest.fixture
def small_large(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(npz, "LARGE", 1 << 20)
    monkeypatch.setattr(npz, "CHUNK", 256 << 10)  # several chunks a large array


@pytest.mark.usefixtures("small_large")
def test_the_file_holds_savez_compressed_s_members_and_npy_bytes(tmp_path) -> None:
    arrays = _arrays()
    npz.write_npz(tmp_path / "mine.npz", arrays)
    np.savez_compressed(tmp_path / "numpy.npz", **arrays)
    with (
        zipfile.ZipFile(tmp_path / "mine.npz") as mine,
        zipfile.ZipFile(tmp_path / "numpy.npz") as ref,
    ):
        assert mine.namelist() == ref.namelist() == [f"{name}.npy" for name in arrays]
        for name, array in arrays.items():
            data = mine.read(f"{name}.npy")  # checks the CRC too
            assert data == ref.read(f"{name}.npy") == _npy_bytes(array), name
            assert mine.getinfo(f"{name}.npy").compress_type == zipfile.ZIP_DEFLATED
    with np.load(tmp_path / "mine.npz", allow_pickle=False) as loaded:  # a plain np.load
        assert loaded.files == list(arrays)
        for name, array in arrays.items():
            assert loaded[name].dtype == array.dtype and loaded[name].shape == array.shape
            assert loaded[name].tobytes() == array.tobytes(), name


def _deflated_size(data: bytes, level: int) -> int:
    """Bytes of ``data`` as a zip member deflated at zlib ``level`` (raw deflate, no header)."""
    deflater = zlib.compressobj(level, zlib.DEFLATED, -15)
    return len(deflater.compress(data)) + len(deflater.flush())


@pytest.mark.usefixtures("small_large")
def test_large_arrays_are_deflated_at_level_1_and_small_ones_at_level_6(tmp_path) -> None:
    """Each member's deflated size is zlib's at that level on its .npy bytes (in this process's
    zlib, whichever build it is): level 1 for the 1 MiB and larger arrays, C-contiguous or not,
    level 6 (savez_compressed's) for the rest, those after a large one too."""
    arrays = _arrays()
    npz.write_npz(tmp_path / "out.npz", arrays)
    large = {"marginals", "labels", "fortran", "strided"}
    assert large == {name for name, array in arrays.items() if array.nbytes >= npz.LARGE}
    with zipfile.ZipFile(tmp_path / "out.npz") as archive:
        for name, array in arrays.items():
            data = _npy_bytes(array)
            size = archive.getinfo(f"{name}.npy").compress_size
            assert size == _deflated_size(data, 1 if name in large else 6), name
            if name in large:  # the sizes tell the levels apart: the check can fail
                assert _deflated_size(data, 1) != _deflated_size(data, 6), name


def test_writes_into_an_open_file_as_replace_file_gives_it(tmp_path) -> None:
    arrays = {"a": np.arange(10), "b": np.array("x")}
    with open(tmp_path / "out.npz", "wb") as file:
        npz.write_npz(file, arrays)
    with np.load(tmp_path / "out.npz") as loaded:
        assert [loaded[k].tolist() for k in loaded.files] == [list(range(10)), "x"]


def test_a_results_npz_is_written_through_it(monkeypatch, tmp_path) -> None:
    """SpCoResult.save writes result.npz with write_npz (it was np.savez_compressed: 4.1 s of
    CPU for a 2.9-million-cell map's result.npz, 2.3 s now), the arrays unchanged."""
    from hand_results import two_rooms

    result = two_rooms()
    frequencies = np.zeros((len(result.labels), len(result.pi)), np.float32)  # [N, L] 3600 B
    frequencies[np.arange(len(result.labels)), result.labels] = 1.0
    result = dataclasses.replace(result, marginals=frequencies)
    monkeypatch.setattr(npz, "LARGE", frequencies.nbytes)  # labels [N] int64: 2400 B
    written: list[str] = []
    write_member = npz._write_member
    monkeypatch.setattr(
        npz,
        "_write_member",
        lambda archive, name, a: written.append(name) or write_member(archive, name, a),
    )
    result.save(tmp_path / "out")
    expected = result._arrays()
    assert written == list(expected)
    with zipfile.ZipFile(tmp_path / "out" / "result.npz") as archive:
        size = archive.getinfo("marginals.npy").compress_size  # the large one: level 1
        assert size == _deflated_size(_npy_bytes(frequencies), 1)
    with np.load(tmp_path / "out" / "result.npz") as loaded:
        assert loaded.files == list(expected)
        for name, array in expected.items():
            assert np.asarray(array).tobytes() == loaded[name].tobytes(), name
            assert np.asarray(array).dtype == loaded[name].dtype, name


def test_a_study_s_label_map_is_written_through_it(monkeypatch, tmp_path) -> None:
    """A study's ``maps/KEY.npz`` (CellStore.put) is write_npz's file (it was
    np.savez_compressed): labels and truth [H, W] int16 are 64 MiB on a map of 33.5 million
    cells, deflated at level 1 then; the arrays read back unchanged."""
    from spcopyro.study.table import CellStore

    rng = np.random.default_rng(1)
    labels = np.repeat(rng.integers(-1, 40, 2000), 50).astype(np.int16).reshape(200, 500)
    label_map = {
        "labels": labels,  # [H, W] int16, 200 kB: the large one here
        "occupancy": np.zeros((200, 500), np.int8),  # [H, W] 100 kB
        "resolution": np.float64(0.05),
        "origin": np.array([-5.0, -12.5]),
    }
    monkeypatch.setattr(npz, "LARGE", labels.nbytes)
    CellStore(tmp_path).put({"key": "k"}, None, label_map)
    data = _npy_bytes(labels)
    assert _deflated_size(data, 1) != _deflated_size(data, 6)  # the check can fail
    with zipfile.ZipFile(tmp_path / "maps" / "k.npz") as archive:
        assert archive.getinfo("labels.npy").compress_size == _deflated_size(data, 1)
        occupancy = _npy_bytes(label_map["occupancy"])
        assert archive.getinfo("occupancy.npy").compress_size == _deflated_size(occupancy, 6)
    with np.load(tmp_path / "maps" / "k.npz") as loaded:
        assert loaded.files == list(label_map)
        for name, array in label_map.items():
            assert np.asarray(array).tobytes() == loaded[name].tobytes(), name
            assert np.asarray(array).dtype == loaded[name].dtype, name
