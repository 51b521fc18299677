"""Writing a drawn figure as a PNG (:func:`save_figure`: at ``DPI``, cropped to its artists),
on a thread of its own where the caller asks for it.

Compressing a figure's pixels into a PNG is a tenth to a third of its time, and Pillow releases
the GIL while it compresses. Inside :func:`background_writes` (what ``spcopyro fit`` uses for its
figures, issue 25 item 1), :func:`save_png` renders the figure into an RGBA buffer in the calling
thread and leaves the PNG to one writer thread, so the next figure is drawn meanwhile; the block
ends when every file is written (and raises the first error). The file is byte for byte the one
:meth:`~matplotlib.figure.Figure.savefig` writes (the same pixels, the same ``Software`` text
chunk and resolution). Outside the block it is :meth:`~matplotlib.figure.Figure.savefig`.
Either way the file is written beside its place and renamed into it
(:func:`~spcopyro._util.outputs.replace_file`): a Ctrl-C leaves the old file or none, never half
of a PNG.
"""

from __future__ import annotations

import contextlib
import io
import os
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.transforms import Bbox

from spcopyro._util.outputs import replace_figure, replace_file
from spcopyro._util.timings import timed
from spcopyro.figures.fonts import any_script

DPI = 150  # of every PNG
PAD_INCHES = 0.1  # around the artists (matplotlib's savefig.pad_inches)

_writer: list[ThreadPoolExecutor] = []  # the one writer of the open block, if any
_pending: list[Future[None]] = []


@contextlib.contextmanager
def background_writes() -> Iterator[None]:
    """PNGs saved by :func:`save_png` inside the block are compressed and written on a thread;
    all are written when the block ends (the first error raised). Not reentrant from threads:
    one block at a time, figures saved from the thread that opened it."""
    if _writer:  # nested: the outer block waits for them
        yield
        return
    executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="spcopyro-png")
    _writer.append(executor)
    try:
        yield
    finally:
        _writer.clear()
        with timed("figure png wait"):  # for the PNGs still being written
            executor.shutdown(wait=True)
        done, _pending[:] = list(_pending), []
        for future in done:
            future.result()  # the first error, raised here


def save_png(fig: Figure, path: str | os.PathLike[str], dpi: float, box: Bbox) -> None:
    """Write ``fig`` at ``dpi`` cropped to ``box`` (inches) as the PNG ``path``: here, or on the
    writer thread of an open :func:`background_writes` block."""
    if not _writer:
        replace_figure(fig, path, dpi=dpi, bbox_inches=box)  # whole or not at all
        return
    buffer = io.BytesIO()
    fig.savefig(buffer, format="rgba", dpi=dpi, bbox_inches=box)
    pixels = buffer.getvalue()
    renderer = getattr(fig.canvas, "renderer", None)  # the Agg renderer it was drawn on
    size = (int(getattr(renderer, "width", 0)), int(getattr(renderer, "height", 0)))
    if size[0] * size[1] * 4 != len(pixels):  # not as drawn here: draw it again, as a PNG
        replace_figure(fig, path, dpi=dpi, bbox_inches=box)
        return
    _pending.append(_writer[0].submit(_write, os.fspath(path), pixels, size, dpi))


def _write(path: str, pixels: bytes, size: tuple[int, int], dpi: float) -> None:
    """The PNG :func:`matplotlib.image.imsave` writes for the RGBA ``pixels`` of ``size``, whole
    or not at all (:func:`~spcopyro._util.outputs.replace_file`)."""
    import matplotlib
    from PIL import Image, PngImagePlugin

    image = Image.frombuffer("RGBA", size, pixels, "raw", "RGBA", 0, 1)
    info = PngImagePlugin.PngInfo()
    info.add_text(
        "Software", f"Matplotlib version{matplotlib.__version__}, https://matplotlib.org/"
    )
    replace_file(path, lambda file: image.save(file, format="png", pnginfo=info, dpi=(dpi, dpi)))


def save_figure(fig: Figure, path: str | os.PathLike[str]) -> Path:
    """Write ``fig`` as a PNG at ``DPI``, cropped to its artists plus ``PAD_INCHES``.

    The crop box is measured on the figure's Agg canvas (:meth:`Figure.get_tightbbox`) at the
    PNG's ``DPI`` and given to :meth:`~Figure.savefig`: the figure is drawn once.
    ``bbox_inches="tight"`` draws it twice (a dry run to find the box, then the PNG), a third of
    the time of a semantic map; the two boxes differ by a few pixels at most. (Measured at the
    figure's own 100 dpi, text is narrower than at 150 dpi: a semantic map's legend reached
    0.2 inch past the box and its longest line was cut.)
    A path without a suffix gets ``.png`` (matplotlib added it, but the path returned, and so
    ``wrote X`` of ``show`` and ``where``, did not; inside :func:`background_writes` the file
    was written without it). Texts of any script: :func:`~spcopyro.figures.fonts.any_script`.
    """
    path = Path(path)
    if not path.suffix:
        path = path.with_suffix(".png")
    path.parent.mkdir(parents=True, exist_ok=True)
    with any_script(fig):
        fig.set_dpi(DPI)  # text is measured as it is drawn in the PNG
        renderer = MeasuredCanvas(fig).get_renderer()
        box = fig.get_tightbbox(renderer).padded(PAD_INCHES)
        save_png(fig, path, DPI, box)  # on a thread inside background_writes()
    return path


class MeasuredCanvas(FigureCanvasAgg):
    """An Agg canvas whose renderers share the sizes of the texts they measure.

    :func:`save_figure` measures the crop box on a renderer of the whole figure, and
    :meth:`~matplotlib.figure.Figure.savefig` then draws on a new one of the cropped size;
    matplotlib keeps a text's size per renderer (``matplotlib.text``'s cache), so the draw
    measured every text (the title, the ticks, the legend's lines, the labels) again: 53 of the
    embedded house's semantic map's 128, 0.025 s of CPU (docs/speed.md). Here every renderer this
    canvas makes answers from one dict, keyed by the text, its font, its ``ismath`` and the
    renderer's dpi, what Agg's ``get_text_width_height_descent`` depends on (not the
    renderer's size): the same sizes, and the same PNG byte for byte."""

    def __init__(self, figure: Figure) -> None:
        super().__init__(figure)
        self._sizes: dict[tuple[object, ...], tuple[float, ...]] = {}

    def get_renderer(self) -> RendererAgg:
        renderer = super().get_renderer()
        if "get_text_width_height_descent" not in vars(renderer):  # a new one: share the sizes
            measure = renderer.get_text_width_height_descent
            sizes, dpi = self._sizes, renderer.dpi

            def shared(s: str, prop: FontProperties, ismath: bool | str) -> tuple[float, ...]:
                key = (s, prop.copy(), ismath, dpi)  # a copy: the text's font may change later
                if key not in sizes:
                    sizes[key] = measure(s, prop, ismath)
                return sizes[key]

            renderer.get_text_width_height_descent = shared  # type: ignore[method-assign]
        return renderer
