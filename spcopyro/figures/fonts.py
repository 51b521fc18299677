"""Texts of any script in the figures: fallback fonts with Japanese (and Chinese) glyphs where
one is installed, and one warning, in words, for the glyphs no font has (issue 22 item 10).

:func:`any_script` wraps a figure's ``savefig``; every figure writer of the package goes through
it (:func:`spcopyro.figures.png.save_figure` and the study and experiment figures)."""

from __future__ import annotations

import contextlib
import logging
import warnings
from collections.abc import Iterator

from matplotlib.figure import Figure
from matplotlib.text import Text

from spcopyro.data.text import tokenize

__all__ = ["CJK_FONTS", "any_script", "quiet_glyph_warnings"]

CJK_FONTS = (
    "Noto Sans CJK JP", "Noto Sans JP", "IPAexGothic", "IPAGothic", "TakaoGothic",
    "Source Han Sans JP", "Hiragino Sans", "Yu Gothic", "MS Gothic", "Noto Sans CJK SC",
    "WenQuanYi Zen Hei",
)  # fmt: skip
"""Fonts with Japanese (and Chinese) glyphs that the figures fall back to, in this order, when
one is installed: words of any script are drawn, not as boxes (issue 22 item 10)."""
_warned_glyphs: set[str] = set()


def _font_families() -> list[str]:
    """matplotlib's sans-serif font first, then every installed font of :data:`CJK_FONTS`."""
    from matplotlib import font_manager, rcParams

    installed = {font.name for font in font_manager.fontManager.ttflist}
    return [*rcParams["font.sans-serif"][:1], *(f for f in CJK_FONTS if f in installed)]


def _covered(families: list[str]) -> set[int]:
    """The code points the ``families`` fonts have glyphs for."""
    from matplotlib import font_manager
    from matplotlib.ft2font import FT2Font

    points: set[int] = set()
    for family in families:
        path = font_manager.findfont(family, fallback_to_default=False)
        points |= set(FT2Font(path).get_charmap())
    return points


def _check_glyphs(artists: list[Text], families: list[str]) -> None:
    """Log once (logger ``"spcopyro"``) the words of a figure's text ``artists`` that no font
    can draw, and how to get a font that can."""
    texts = {t.get_text() for t in artists}
    strange = {c for text in texts for c in text if ord(c) > 0x24F and not c.isspace()}
    if not strange:
        return
    covered = _covered(families)
    missing = sorted(c for c in strange if ord(c) not in covered and c not in _warned_glyphs)
    if not missing:
        return
    _warned_glyphs.update(missing)
    # the words as the data holds them: not "'台所'?" of the title "where is '台所'?"
    words = sorted({w for text in texts for w in tokenize(text) if set(w) & set(missing)})[:5]
    logging.getLogger("spcopyro").warning(
        "the figures' fonts have no glyphs for %s (in %s): they are drawn as boxes; install a "
        "font that has them (e.g. Debian's fonts-noto-cjk for Japanese) and the figures use it",
        "".join(missing[:10]),
        ", ".join(words),
    )


@contextlib.contextmanager
def any_script(fig: Figure) -> Iterator[None]:
    """Inside it, ``fig``'s texts are drawn in the first font of :func:`_font_families` that has
    each glyph (where a fallback font is installed), glyphs no font has are told once in words
    (:func:`_check_glyphs`), and matplotlib's per-glyph warnings are not shown: save it there."""
    families = _font_families()
    artists = fig.findobj(Text)
    if len(families) > 1:  # fallback fonts installed; else every text keeps its own (the same)
        for text in artists:
            text.set_fontfamily(families)  # any script: the first font that has the glyph
    _check_glyphs(artists, families)
    with quiet_glyph_warnings():
        yield


@contextlib.contextmanager
def quiet_glyph_warnings() -> Iterator[None]:
    """matplotlib's per-glyph "Glyph ... missing from font" warnings not shown (:func:`any_script`
    tells the missing glyphs once, in words): around a figure's layout measured before it is
    saved (``tight_layout``)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Glyph .* missing from font")
        yield
