"""The command-line plumbing every benchmark script shares: the dataset, houses asked for by
name, what ``--quick`` sets, one-line errors and Ctrl-C.

Imports nothing of the package at module level (``fixed_cost.py`` times fits as fresh
processes and keeps its own imports light); the scripts import it from their own folder, which
is on ``sys.path`` when they run.

* :func:`dataset_root`: the public dataset, or a one-line note and None (scripts that skip the
  public houses or use a synthetic stand-in), or a one-line error and exit 2 (scripts that need
  it, and a ``--dataset`` that is not one).
* :func:`house_folder`: a house asked for by name, or a one-line error naming the houses there.
* :func:`quick_or`: the rule for ``--quick``: it only changes the defaults; an option given
  explicitly wins over ``--quick``'s value (options whose default depends on ``--quick`` default
  to None in the parser).
* :func:`results_path`: the JSON's path: ``--out``, else ``NAME.json`` (``NAME_quick.json``
  under ``--quick``).
* :func:`run_main`: makes an ``--out``'s folder, runs ``main``; Ctrl-C ends it with one line
  and exit status 130.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NoReturn, TypeVar

SCRIPT_DIR = Path(__file__).resolve().parent
ROOT = SCRIPT_DIR.parent
if str(ROOT) not in sys.path:  # the checkout's package when it is not installed
    sys.path.append(str(ROOT))

from spcopyro._util.arguments import (  # noqa: E402  (light: imports nothing of the package)
    integer_at_least,
    non_negative_number,
    number_type,
    positive_number,
)

T = TypeVar("T")

COUNT = integer_at_least(1)
"""argparse type of a count of sweeps, seeds, repeats, threads...: an int >= 1."""
INDEX = integer_at_least(0)
"""argparse type of a seed or a count that may be 0: an int >= 0."""
SECONDS = positive_number("time budget is seconds")
"""argparse type of a time budget: a finite float > 0."""
METRES = non_negative_number("radius is metres")
"""argparse type of a radius: a finite float >= 0."""
WAIT = non_negative_number("wait is seconds")
"""argparse type of --wait-idle: a finite float >= 0 (0: do not wait)."""


fraction = number_type(lambda v: 0.0 <= v <= 1.0, lambda t: f"{t!r}: a share is a number in [0, 1]")
"""argparse type of a share: a float in [0, 1]."""


GAMMA = non_negative_number("Potts coupling gamma is a number")
"""argparse type of ``--gamma``: a finite float >= 0 (:class:`spcopyro.config.SpCoConfig`'s
rule, checked before anything runs instead of as a traceback from the first fit)."""


def preset_name(text: str) -> str:
    """argparse type of a preset's name: one of :data:`spcopyro.config.PRESETS`, else a usage
    error listing them (not a ``ValueError`` traceback from the first fit)."""
    from spcopyro.config import PRESETS  # standard library only

    if text not in PRESETS:
        raise argparse.ArgumentTypeError(
            f"unknown preset {text!r}; choose from {', '.join(sorted(PRESETS))}"
        )
    return text


def preset_names(text: str) -> str:
    """argparse type of comma-separated presets ("paper-dp,auto"): each non-empty part, spaces
    stripped, a :func:`preset_name`, and at least one; the text is returned as given."""
    parts = [part.strip() for part in text.split(",") if part.strip()]
    if not parts:
        raise argparse.ArgumentTypeError(f"{text!r}: no preset named")
    for part in parts:
        preset_name(part)
    return text


def counts(text: str) -> list[int]:
    """argparse type of comma-separated counts ("1,8,32"): each an int >= 1."""
    return [COUNT(part.strip()) for part in text.split(",")]


# JSON files a script writes as it goes (its partial results), named in the Ctrl-C line.
WRITTEN: list[Path] = []


def fail(message: str) -> NoReturn:
    """Print ``SCRIPT: error: message`` on stderr and exit 2 (argparse's usage-error status)."""
    print(f"{Path(sys.argv[0]).name}: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def quick_or(value: T | None, quick: bool, quick_value: T, full_value: T) -> T:
    """An option's value: as given (not None) wins; else ``quick_value`` under ``--quick``,
    ``full_value`` otherwise."""
    if value is not None:
        return value
    return quick_value if quick else full_value


def results_path(out: str | os.PathLike[str] | None, name: str, quick: bool) -> Path:
    """Where a script writes its JSON: ``out`` (``--out``) as given, else
    ``benchmarks/NAME.json``, or ``benchmarks/NAME_quick.json`` under ``--quick``: a smoke run
    never overwrites the full run's results (which can take an hour)."""
    if out is not None:
        return Path(out)
    return SCRIPT_DIR / (f"{name}_quick.json" if quick else f"{name}.json")


def dataset_root(
    path: str | os.PathLike[str] | None = None,
    without: str | None = None,
    needed_by: str | None = None,
) -> Path | None:
    """The public dataset's root (``path``, i.e. ``--dataset``, else ``$SPCOPYRO_DATA``, else
    ../shared/data/spcomapping; :func:`spcopyro.data.find_dataset_root`).

    Not found (or ``$SPCOPYRO_DATA`` names a folder that is not one): with ``without`` (what the
    script does instead, e.g. "the public houses are skipped") a one-line note on stderr and
    None; with ``without`` None (the script needs the dataset) a one-line error and exit 2. A
    ``path`` given explicitly that is not a dataset is always an error. ``needed_by`` (e.g.
    "--houses room1dk5"), when given, starts the error line."""
    lead = f"{needed_by}: " if needed_by else ""
    from spcopyro.data.dataset import find_dataset_root

    try:
        root = find_dataset_root(path)
    except FileNotFoundError as error:
        if path is not None or without is None:
            fail(f"{lead}{error}")
        print(f"note: {error}; {without}", file=sys.stderr)
        return None
    if root is None:
        where = "no public dataset found ($SPCOPYRO_DATA, ../shared/data/spcomapping, --dataset)"
        if without is None:
            fail(f"{lead}{where}")
        print(f"note: {where}; {without}", file=sys.stderr)
    return root


def available_houses(root: Path) -> list[str]:
    """The houses of the dataset at ``root`` (:func:`spcopyro.data.list_houses`)."""
    from spcopyro.data.dataset import list_houses

    return list_houses(root)


def house_folder(root: Path | None, name: str, option: str = "--houses") -> Path:
    """The folder of the public house ``name`` asked for by ``option``: a one-line error (exit
    2) naming the house and the houses there when the dataset lacks it or was not found."""
    if root is None:
        fail(f"{option} {name}: the public dataset was not found ($SPCOPYRO_DATA, "
             "../shared/data/spcomapping, --dataset)")  # fmt: skip
    houses = available_houses(root)
    if name not in houses:
        fail(f"{option}: no house {name!r} in {root}; houses: {', '.join(houses) or 'none'}")
    return Path(root) / name


def check_houses(root: Path | None, names: Sequence[str], option: str = "--houses",
                 synthetic: Sequence[str] = ()) -> None:  # fmt: skip
    """:func:`house_folder` for every name of ``names`` not in ``synthetic`` (the script's own
    synthetic houses); an unknown name without the dataset is named with the choices."""
    for name in names:
        if name in synthetic:
            continue
        if root is None and synthetic:
            fail(f"{option} {name}: not one of {', '.join(synthetic)}, and the public "
                 "dataset was not found ($SPCOPYRO_DATA, ../shared/data/spcomapping, "
                 "--dataset)")  # fmt: skip
        house_folder(root, name, option)


def prepare_out_folder(argv: Sequence[str]) -> None:
    """Create the folder of an ``--out`` given in ``argv`` (``--out PATH`` or ``--out=PATH``)
    before the script runs: a folder that did not exist used to fail the script after its
    measurements, when it wrote the JSON (four scripts created it, the others did not). A
    folder that cannot be made, or an ``--out`` that is a folder (the run failed at its end,
    writing the JSON, with IsADirectoryError), is a one-line error (exit 2) before anything
    runs."""
    values = [b for a, b in zip(argv, argv[1:], strict=False) if a == "--out"]
    values += [a.split("=", 1)[1] for a in argv if a.startswith("--out=")]
    for value in values:
        if value.endswith(("/", os.sep)) or Path(value).is_dir():  # the JSON: written at the end
            fail(f"--out {value}: is a folder; give the JSON file's name, e.g. "
                 f"{os.path.join(value, Path(sys.argv[0]).stem + '.json')}")  # fmt: skip
        folder = Path(value).parent
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            fail(f"--out {value}: cannot make its folder {folder}: {error.strerror or error}")


def run_main(main: Callable[[], int | None]) -> NoReturn:
    """``sys.exit(main())``, except that Ctrl-C (KeyboardInterrupt) ends the script with one
    line (what was written so far, :data:`WRITTEN`, or "no JSON written") and status 130
    instead of a traceback. An ``--out`` on the command line gets its folder first
    (:func:`prepare_out_folder`)."""
    if "-h" not in sys.argv[1:] and "--help" not in sys.argv[1:]:
        prepare_out_folder(sys.argv[1:])
    script = getattr(main, "__module__", None) == "__main__"  # not a test calling run_main
    try:
        code = main()
    except KeyboardInterrupt:
        written = [str(p) for p in WRITTEN if p.is_file()]
        what = f"{', '.join(written)} holds the results so far" if written else "no JSON written"
        print(f"\ninterrupted: {what}", file=sys.stderr)
        if script:
            _quiet_ctrl_c_at_exit(130)
        raise SystemExit(130) from None
    if script:
        _quiet_ctrl_c_at_exit(code or 0)
    raise SystemExit(code or 0)


def _quiet_ctrl_c_at_exit(status: int) -> None:
    """Once ``main`` is done (its JSON written, or the interrupt reported), a Ctrl-C during the
    interpreter's shutdown (torch's and numba's exit callbacks) ends the process at once with
    ``status``: it printed "Exception ignored in atexit callback" and a KeyboardInterrupt
    traceback after "wrote ...", or died of SIGINT (status -2) with no line at all."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, lambda *_: os._exit(status))
