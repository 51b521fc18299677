"""Reports and figures rewritten in place are replaced whole (review of b029080): a Ctrl-C while
``report.md`` or a ``show``/``where`` PNG was being written
left half of it, while the line said the cells (or the files) were kept whole. Each is written
beside its place and renamed into it (:func:`spcopyro._util.outputs.replace_file`), so a stop
mid-write leaves the old file. The writes are cut here mid-file by an interrupt: an in-place
write (``Path.write_text``, a PNG saved to its path) and a replaced one alike."""

from __future__ import annotations

import os
import pathlib

import pytest
from matplotlib.figure import Figure
from PIL import Image

from spcopyro._util.outputs import replace_figure, replace_text


@pytest.fixture
def cut_writes(monkeypatch):
    """Every text write and PNG save stops half-way with a KeyboardInterrupt (what Ctrl-C raises
    wherever Python is): ``Path.write_text`` (in place), a file :func:`replace_file` opens (the
    staging file beside) and Pillow's PNG writer (matplotlib's and ``figures.png``'s)."""
    real_fdopen = os.fdopen

    def write_text(self, text, *args, **kwargs):
        with open(self, "w") as file:
            file.write(text[: len(text) // 2])
        raise KeyboardInterrupt

    class HalfFile:
        def __init__(self, file):
            self.file = file

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.file.close()

        def write(self, data):
            self.file.write(data[: len(data) // 2])
            self.file.flush()
            raise KeyboardInterrupt

    def save_png(image, file, name):
        file.write(b"\x89PNG half")
        raise KeyboardInterrupt

    monkeypatch.setattr(pathlib.Path, "write_text", write_text)
    monkeypatch.setattr(os, "fdopen", lambda *a, **k: HalfFile(real_fdopen(*a, **k)))
    monkeypatch.setitem(Image.SAVE, "PNG", save_png)


def _figure() -> Figure:
    fig = Figure(figsize=(2, 1.5))
    fig.add_subplot().plot([0, 1, 2], [2, 0, 1])
    return fig


def test_a_study_report_stays_the_old_one_when_stopped_mid_write(tmp_path, cut_writes):
    """report.md of the study engine (each study command's too) was written in place."""
    from spcopyro.study.report import write_report

    (tmp_path / "results.csv").write_bytes(b"status\n")  # a table of no rows
    (tmp_path / "report.md").write_bytes(b"the earlier run's report\n")
    with pytest.raises(KeyboardInterrupt):
        write_report(tmp_path / "results.csv", tmp_path / "report.md")
    assert (tmp_path / "report.md").read_bytes() == b"the earlier run's report\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.md", "results.csv"]


def test_a_show_or_where_png_stays_the_old_one_when_stopped_mid_write(tmp_path, cut_writes):
    """save_figure (show, where, fit's figures) saved the PNG to its path: here, and on the
    writer thread of background_writes."""
    from spcopyro.figures.png import background_writes, save_figure

    for name in ("here.png", "thread.png"):
        (tmp_path / name).write_bytes(b"the old figure")
    with pytest.raises(KeyboardInterrupt):
        save_figure(_figure(), tmp_path / "here.png")
    with pytest.raises(KeyboardInterrupt), background_writes():
        save_figure(_figure(), tmp_path / "thread.png")
    for name in ("here.png", "thread.png"):
        assert (tmp_path / name).read_bytes() == b"the old figure", name
    assert sorted(p.name for p in tmp_path.iterdir()) == ["here.png", "thread.png"]


def test_replaced_text_and_figures_are_those_written_in_place(tmp_path):
    """The same bytes as ``Path.write_text`` and ``savefig`` to the path (a PNG and a format
    read from another suffix); ``figures.png``'s PNGs, here and on its thread, too."""
    from matplotlib.transforms import Bbox

    from spcopyro.figures.png import background_writes, save_png

    text = "↓ wrong cells\nα\n"
    (tmp_path / "a.md").write_text(text, encoding="utf-8")
    replace_text(tmp_path / "b.md", text)
    assert (tmp_path / "a.md").read_bytes() == (tmp_path / "b.md").read_bytes()
    fig = _figure()
    for suffix in (".png", ".jpg"):
        fig.savefig(tmp_path / f"a{suffix}", dpi=80, bbox_inches="tight")
        replace_figure(fig, tmp_path / f"b{suffix}", dpi=80, bbox_inches="tight")
        assert (tmp_path / f"a{suffix}").read_bytes() == (tmp_path / f"b{suffix}").read_bytes()
    box = Bbox([[0, 0], [2, 1.5]])
    fig.savefig(tmp_path / "plain.png", dpi=90, bbox_inches=box)
    save_png(fig, tmp_path / "here.png", 90, box)
    with background_writes():
        save_png(fig, tmp_path / "thread.png", 90, box)
    for name in ("here.png", "thread.png"):
        assert (tmp_path / name).read_bytes() == (tmp_path / "plain.png").read_bytes(), name
