"""Command-line argument types shared by every command's parser (imports nothing of the
package, so a parser at any layer may use them)."""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Callable

__all__ = [
    "MAX_SEED",
    "figure_path",
    "integer_at_least",
    "non_negative_number",
    "number_type",
    "positive_number",
    "seed",
]


MAX_SEED = 2**63 - 1
"""The largest seed: :meth:`torch.Generator.manual_seed` takes a signed 64-bit integer (here,
not beside the seed checks that import torch, so that ``--seed``'s parser imports none)."""


def integer_at_least(minimum: int) -> Callable[[str], int]:
    """An argparse ``type``: the text as an int >= ``minimum``, else a usage error naming the
    value ("must be an integer >= 1, got '0'")."""

    def parse(value: str) -> int:
        try:
            number = int(value)
        except ValueError:
            number = minimum - 1
        if number < minimum:
            raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, got {value!r}")
        return number

    return parse


def seed(value: str) -> int:
    """An argparse ``type`` for ``--seed``: an integer in 0 .. :data:`MAX_SEED` (argparse names
    the option on an error)."""
    number = integer_at_least(0)(value)
    if number > MAX_SEED:
        raise argparse.ArgumentTypeError(f"must be at most 2**63 - 1 = {MAX_SEED}, got {value!r}")
    return number


def number_type(
    accept: Callable[[float], bool], message: Callable[[str], str]
) -> Callable[[str], float]:
    """An argparse ``type``: the text as a float that ``accept`` takes, else a usage error with
    ``message(text)`` (text that is no number is refused the same way: NaN is accepted by no
    range check)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not accept(value):
            raise argparse.ArgumentTypeError(message(text))
        return value

    return parse


def _finite_number(what: str, positive: bool) -> Callable[[str], float]:
    """An argparse ``type``: a finite float >= 0 (> 0 if ``positive``), else a usage error
    naming the value and ``what`` it is ("'-1': the area is square metres > 0")."""
    bound = "> 0" if positive else ">= 0"
    return number_type(
        lambda v: math.isfinite(v) and (v > 0 if positive else v >= 0),
        lambda text: f"{text!r}: the {what} {bound}",
    )


def non_negative_number(what: str) -> Callable[[str], float]:
    """A finite float >= 0 (:func:`_finite_number`)."""
    return _finite_number(what, positive=False)


def positive_number(what: str) -> Callable[[str], float]:
    """A finite float > 0 (:func:`_finite_number`)."""
    return _finite_number(what, positive=True)


def figure_path(value: str) -> str:
    """An argparse ``type`` for a figure's ``--out``: a name whose suffix matplotlib can write
    (none: ``.png``), else a usage error listing the formats, before anything is computed or
    printed (matplotlib's own error came after the answer and did not name the option).
    A folder is refused, and so is a file where a folder of the path would be (``--out /tmp``
    wrote ``/tmp.png``, beside the folder; ``--out FILE/x.png`` failed with "[Errno 17] File
    exists")."""
    if not value.strip():
        raise argparse.ArgumentTypeError(f"{value!r}: an empty file name; give the figure's")
    if value.endswith(("/", os.sep)) or os.path.isdir(value):
        raise argparse.ArgumentTypeError(
            f"{value!r} is a folder: give the figure's file name in it, e.g. "
            f"{os.path.join(value, 'figure.png')!r}"
        )
    # not at start-up: --help needs neither
    from spcopyro._util.folder_commit import absolute_path
    from spcopyro._util.outputs import nearest_existing

    parent = nearest_existing(absolute_path(value).parent)
    if parent.exists() and not parent.is_dir():
        raise argparse.ArgumentTypeError(
            f"{value!r}: {str(parent)!r} is a file, not a folder the figure could be written in"
        )
    suffix = value.rsplit(".", 1)[-1].lower() if "." in value.rsplit("/", 1)[-1] else ""
    if suffix:
        from matplotlib.backend_bases import FigureCanvasBase  # only when a suffix is given

        formats = sorted(FigureCanvasBase.get_supported_filetypes())
        if suffix not in formats:
            raise argparse.ArgumentTypeError(
                f"{value!r}: matplotlib cannot write .{suffix} figures; use one of "
                f"{', '.join(formats)}"
            )
    return value
