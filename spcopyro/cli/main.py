"""The ``spcopyro`` command line: simulate, show, fit, where, experiment, compare-inference,
features, features-head, export, import-bag, simulate-bag.

DATA is a house folder in the public dataset's layout (its map at ``DATA/../map/NAME.yaml``), e.g.
``../shared/data/spcomapping/room1dk5``, or one written by ``spcopyro simulate``. Where DATA is
left out, the embedded default is used: the synthetic house of seed 0, generated in memory.

This module holds the parser, :func:`main`, the logging set-up and the small commands (``show``,
``where``); ``simulate`` is in :mod:`spcopyro.cli.simulate` (``simulate --map`` runs
:mod:`spcopyro.robot.map_simulation`), ``fit`` in :mod:`spcopyro.cli.fit`, ``experiment``,
``compare-inference`` and ``ablation`` in :mod:`spcopyro.study.commands`, ``features`` in
:mod:`spcopyro.features.cli`, ``export`` in :mod:`spcopyro.cli.export`, ``import-bag`` and
``simulate-bag`` in :mod:`spcopyro.robot.rosbag.cli`, and what they share (DATA, the house
summary, argument types, the help formatter) in :mod:`spcopyro.cli.common`.
"""

from __future__ import annotations

import argparse
import errno
import gc
import logging
import os
import shlex
import sys
from pathlib import Path
from typing import NoReturn

import numpy as np

from spcopyro import __version__
from spcopyro._util.arguments import figure_path, non_negative_number
from spcopyro._util.interrupts import caused_by_interrupt, signals_deferred
from spcopyro._util.messages import plural, shown_bytes
from spcopyro._util.process_exit import exit_process, may_skip_teardown
from spcopyro.cli.common import (
    DASH_WORDS,
    CommandParser,
    _HelpFormatter,
    _load,
    _summary,
    figure_file,
    load_fit,
    other_word_note,
    refuse_fit_files,
)
from spcopyro.cli.fit_parser import add_parser as add_fit_parser
from spcopyro.cli.interrupted import interrupted_line
from spcopyro.cli.out_names import probability_figure
from spcopyro.cli.simulate import add_parser as add_simulate_parser

logger = logging.getLogger("spcopyro")


def _show(args: argparse.Namespace) -> int:
    if args.graph:
        from spcopyro.cli.navigate import show_graph
        from spcopyro.robot.navigation.places import DEFAULT_MIN_AREA

        args.min_area = DEFAULT_MIN_AREA if args.min_area is None else args.min_area
        return show_graph(args)
    if args.min_area is not None:  # it was ignored silently
        raise ValueError(f"--min-area {args.min_area:g} sizes the places of --graph: add "
                         "--graph (DATA a fit's folder) or leave it out")  # fmt: skip
    from spcopyro._util.outputs import missing_fit_markers
    from spcopyro.figures.plotting import plot_house

    if args.data and not missing_fit_markers(Path(args.data)):
        figures = "its figures are in it already"
        if not (Path(args.data) / "semantic_map.png").is_file():
            figures = "it was fitted with --no-figures (fit again without it to draw them)"
        from spcopyro.cli.fit_warnings import fit_warnings_note

        raise ValueError(
            f"{args.data} is the output folder of `spcopyro fit`, not a house folder: "
            f"{figures}{fit_warnings_note(Path(args.data))}; to draw its place graph: "
            f"{shlex.join(['spcopyro', 'show', args.data, '--graph', '--out', args.out])}"
        )  # a runnable command, last: `show OUT --graph` alone was refused for its missing --out
    house = _load(args.data)
    print(_summary(house))
    print(f"wrote {plot_house(house, args.out)}")
    return 0


def _check_where_out(result_dir: str, out: str) -> None:
    """``where --out``: refuse a figure (or its ``_probability`` sibling) that would replace
    one of the fit's own files (its manifest, :func:`spcopyro._util.outputs.fit_written`)."""
    refuse_fit_files(result_dir, out, [figure_file(out), probability_figure(Path(out).resolve())])


def _where(args: argparse.Namespace) -> int:
    from spcopyro.results.concept_words import WORDS_NOT_MODELLED, shown_top_words, words_modelled
    from spcopyro.results.result import UnknownWordError
    from spcopyro.results.where import region_piece_sizes, runner_up_line, shared_answer_note

    if args.out:
        _check_where_out(args.result, args.out)
    result, saved = load_fit(args.result, [args.word])  # a saved 'stove.' is 'stove', as said
    try:
        answer = result.where(args.word, prior=args.prior)
    except UnknownWordError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2  # a bad argument, as every other error of the command line
    note = other_word_note(args.word, answer.word, saved)  # `where OUT -- -tv`: 'tv', said
    if note:
        print(f"warning: {note}", file=sys.stderr)
    grid = result.grid
    cells = np.argwhere(answer.region)  # [n, 2] (row, col)
    xy = grid.cell_to_world(cells)
    top = shown_top_words(result, answer.concept, 3)
    words = ", ".join(f"{w} ({p:.2f})" for w, p in top)
    distinctive = result.distinctive_words(answer.concept, 3)
    if result.heard(answer.concept) == 0:
        words = "none, no words heard here"
    elif not words_modelled(result):  # its warnings say what the answer is then
        words = WORDS_NOT_MODELLED
    elif distinctive:
        words += "; distinctive: " + ", ".join(f"{w} x{r:.1f}" for w, r, _ in distinctive)
    print(f"'{answer.word}' is concept {answer.concept} (p(concept | word) = "
          f"{answer.probability:.3f}, "
          f"{answer.prior} prior; its words: {words})")  # fmt: skip
    if answer.runner_up is not None:
        print(runner_up_line(answer))  # with what its Bayes factor means
    if len(cells):
        half = grid.resolution / 2  # xy are cell centres: the region's edges lie half out
        (x0, y0), (x1, y1) = xy.min(0) - half, xy.max(0) + half
        cx, cy = xy.mean(0)
        # [count] largest first, joined as the fit's neighbourhood (as the 'strewn' warning)
        sizes = region_piece_sizes(answer.region, result.config.connectivity)
        count = len(sizes)
        listed = ", ".join(map(str, sizes[:4])) + ", ..." if count > 4 else (
            ", ".join(map(str, sizes[:-1])) + f" and {sizes[-1]}")  # fmt: skip
        apart = f" in {count} pieces of {listed} cells" if count > 1 else ""  # centre: between
        print(f"region: {plural(len(cells), 'cell')} ({len(cells) * grid.resolution**2:.2f} m^2)"
              f"{apart}, centre x={cx:.2f} y={cy:.2f}{' (of them all)' * bool(apart)}, spanning "
              f"x {x0:.2f}..{x1:.2f}, y {y0:.2f}..{y1:.2f} m")  # fmt: skip
    for warning in answer.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    shared = shared_answer_note(answer)  # one concept answering 'toilet' and 'kitchen'
    if shared:
        print(f"note: {shared}")
    from spcopyro.results import uncertainty as per_cell

    probability = per_cell.where_probability(result, answer.word, args.prior)  # [N]
    source = per_cell.marginals_source(result)  # q(C) of a method, or a sampler's frequencies
    unmapped = per_cell.unmapped_note(result)
    source += f"; {unmapped}" if unmapped else ""
    # [N] bool: the region's cells (free cells in raster order, as label_image)
    print(per_cell.threshold_line(probability, answer.region[grid.free], source))
    if args.out:
        from spcopyro.figures.plotting import plot_where, plot_where_probability

        # the [N] above, computed once for the line and both figures (not kept on the result)
        print(f"wrote {plot_where(result, answer, args.out, probability)}")
        probability_png = probability_figure(Path(args.out))
        written = plot_where_probability(
            result, answer.word, probability_png, args.prior, probability
        )
        print(f"wrote {written}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The ``spcopyro`` parser, every command with its options. Building it imports neither
    torch, pyro nor numba (``spcopyro --help``, ``where``, ``show`` and ``export`` run without
    them; the commands that need them import them when they run)."""
    parser = CommandParser(  # its commands are CommandParsers too (add_subparsers' parser_class)
        prog="spcopyro",
        description="SpCoMapping: semantic maps from an occupancy grid, images and words.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log details (INFO)")
    sub = parser.add_subparsers(dest="command", required=True)

    add_simulate_parser(sub)  # simulate

    p = sub.add_parser("show", help="draw a house and its observations; print a summary")
    p.add_argument("data", nargs="?", help="house folder (default: the synthetic house)")
    p.add_argument("--out", required=True, type=figure_path, help="PNG file to write")
    p.add_argument("--graph", action="store_true", help="DATA is a fit's output folder: draw "
                   "its place graph (regions as nodes, shared borders and doorways as edges) "
                   "and write it as JSON beside the PNG (X.json for --out X.png)")  # fmt: skip
    p.add_argument("--min-area", type=non_negative_number("area is square metres"), default=None,
                   metavar="M2", help="with --graph: smaller regions are not places "
                   "(default: 0.25)")  # fmt: skip
    p.set_defaults(func=_show)

    add_fit_parser(sub)  # fit

    p = sub.add_parser("where", help='answer "where is WORD?" from a fitted result')
    p.add_argument("result", help="output folder of `spcopyro fit`")
    p.add_argument("word", help="the word to look up")
    p.add_argument("--out", type=figure_path,
                   help="also draw the answer over the semantic map into this PNG, "
                   "and the per-cell probability of the word's place into "
                   "<name>_probability with the same suffix (default: no PNG)")  # fmt: skip
    p.add_argument(
        "--prior",
        choices=("area", "pi"),
        default="area",
        help="p(C) in eq. (19): a concept's share of the map (default) or pi (the paper's eq. 19, "
        "which weighs a one-cell speck like a room)",
    )
    p.set_defaults(func=_where)

    from spcopyro.study.commands import add_parser as add_study_aliases

    add_study_aliases(sub)  # experiment, compare-inference, ablation (shipped studies)

    from spcopyro.features.cli import add_parser as add_features_parsers

    add_features_parsers(sub)  # features, features-head
    from spcopyro.cli.export import add_parser as add_export_parser

    add_export_parser(sub)  # export
    from spcopyro.robot.rosbag.cli import add_parser as add_rosbag_parsers

    add_rosbag_parsers(sub)  # import-bag, simulate-bag
    from spcopyro.cli.navigate import add_parser as add_navigate_parser

    add_navigate_parser(sub)  # navigate
    from spcopyro.cli.study import add_parser as add_study_parser

    add_study_parser(sub)  # study
    for command in (parser, *sub.choices.values()):
        command.formatter_class = _HelpFormatter
    for name, dash_word in DASH_WORDS.items():  # `where OUT -tv`: say how to give such a word
        sub.choices[name].dash_word = dash_word
    return parser


class _LowerCaseLevel(logging.Formatter):
    """``warning: message`` (as the command's own messages), not ``WARNING: message``."""

    def format(self, record: logging.LogRecord) -> str:  # a path's byte 0xe9 as \xe9
        return f"{record.levelname.lower()}: {shown_bytes(record.getMessage())}"


class _StderrHandler(logging.StreamHandler):
    """Writes to whatever ``sys.stderr`` is when a message comes (not when it was made); while a
    tqdm progress bar is shown, through ``tqdm.write``, which moves the bar below the message
    (a warning was stuck onto the bar's line: "cells 0/1: 0%|...]warning: ...")."""

    @property
    def stream(self):  # noqa: D102
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:
        del value

    def emit(self, record: logging.LogRecord) -> None:  # noqa: D102
        bars = sys.modules.get("tqdm.std")  # never imported here: a bar imported it
        if bars is None or not getattr(bars.tqdm, "_instances", None):
            super().emit(record)
            return
        try:
            bars.tqdm.write(self.format(record), file=sys.stderr)
        except Exception:  # noqa: BLE001 - logging's own rule: report, never raise
            self.handleError(record)


def _configure_logging(level: int) -> None:
    """The library's messages (logger ``spcopyro``) on stderr, each once."""
    logger.setLevel(level)
    if not any(isinstance(h, _StderrHandler) for h in logger.handlers):
        handler = _StderrHandler()
        handler.setFormatter(_LowerCaseLevel())
        logger.addHandler(handler)


def _error_line(error: BaseException) -> str:
    """The one line an error is told in: a full disk says so and names the file being written
    (issue 22 item 10: it was a bare "[Errno 28] No space left on device")."""
    if isinstance(error, OSError) and error.errno == errno.ENOSPC:
        where = f" while writing {error.filename}" if error.filename else ""
        return (
            f"the disk is full{where} ({error.strerror}): free some space or choose another "
            "--out; a fit's staging folder is removed, its output left as it was"
        )
    return shown_bytes(str(error))  # a path's byte 0xe9 as \xe9 (a folder b"caf\xe9")


COORDINATE_OPTIONS = ("--start",)
"""Options whose value is a point ``X,Y``, which may start with a minus sign."""


def attach_negative_coordinates(argv: list[str]) -> list[str]:
    """``--start -0.5,-1`` as ``--start=-0.5,-1``: argparse reads a value that starts with a
    minus sign and is not a plain number as an option, and answered "expected one argument"."""
    joined: list[str] = []
    k = 0
    while k < len(argv):
        value = argv[k + 1] if k + 1 < len(argv) else ""
        if argv[k] in COORDINATE_OPTIONS and value[:1] == "-" and value[1:2] in set("0123456789."):
            joined.append(f"{argv[k]}={value}")
            k += 2
        else:
            joined.append(argv[k])
            k += 1
    return joined


BROKEN_PIPE = 141
"""Exit status when the command's output pipe closed early: 128 + SIGPIPE, what a shell reports
for a program that a closed pipe ends (``head`` read what it wanted)."""


def _silence_stdout() -> None:
    """Point standard output at /dev/null, so that the interpreter's flush at exit does not
    fail again on the closed pipe (Python's documentation on SIGPIPE)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # stdout without a file descriptor (a test's capture)
        pass


def main(argv: list[str] | None = None) -> int:
    given = attach_negative_coordinates(list(sys.argv[1:] if argv is None else argv))
    parser = build_parser()
    args = parser.parse_args(given)
    if argv is not None:
        args.argv = list(argv)
    _configure_logging(logging.INFO if args.verbose else logging.WARNING)
    stop: BaseException = KeyboardInterrupt()
    try:  # a second Ctrl-C before _say_interrupted's guard (at its call): said as the first
        try:
            return args.func(args)
        except BrokenPipeError:  # `spcopyro where OUT kitchen | head -1`: the reader has left
            _silence_stdout()
            return BROKEN_PIPE
        except (OSError, ValueError) as error:  # bad input: one clear line, no traceback
            print(f"error: {_error_line(error)}", file=sys.stderr)
            # a Ctrl-C held while a commit failed (folder_commit.commit_folder; an OutputError of
            # it)
            if not any(getattr(e, "signalled", None) for e in (error, error.__context__)):
                return 2
        except KeyboardInterrupt as interrupt:  # Ctrl-C: one line, no traceback (fit says more)
            stop = interrupt
        except SystemError as error:  # Ctrl-C inside a numba call (spcopyro._util.interrupts)
            if not caused_by_interrupt(error):
                raise
            stop = error
        return _say_interrupted(args, stop)
    except KeyboardInterrupt:
        return _say_interrupted(args, stop)


def _say_interrupted(args: argparse.Namespace, stop: BaseException) -> int:
    """Print the line of a Ctrl-C (:func:`interrupted_line`: which command, what of its
    ``--out``) unless ``stop.said`` (a study has said how far it got); 130. A second Ctrl-C (the
    first held through a commit, :func:`spcopyro._util.folder_commit.commit_folder`) stops nothing
    more: one as the line is said is dropped, one before that is caught and the line said."""
    said = False
    while True:
        try:
            with signals_deferred(lambda signum, frame: None):
                if not (said or getattr(stop, "said", False)):
                    print(interrupted_line(args), file=sys.stderr)
                said = True
            return 130
        except KeyboardInterrupt:  # before the deferring handler was in place, or as it left
            continue


def console_main() -> NoReturn:
    """The ``spcopyro`` console script and ``python -m spcopyro``: :func:`main`, then exit.

    Before exiting, :func:`gc.freeze` moves every object alive into the collector's permanent
    generation, so the interpreter's shutdown skips its final garbage collections over the
    hundreds of thousands of objects torch's import creates (about 0.5 s of every command's exit
    on a 2-core machine; ``benchmarks/fixed_cost.py``). The outputs are all written and closed
    by then, and the standard streams are still flushed at exit. Only the command does this: a
    program calling :func:`main` keeps its collector as it was. Run as the process's own program
    (the console script, ``python -m spcopyro``), it then ends the process without the
    interpreter's teardown, once the threads, the exit handlers and the streams are done
    (:mod:`spcopyro._util.process_exit`: 0.2-0.4 s of a fit's exit).
    """
    try:
        code = main()
    finally:  # also after --help, --version and usage errors (argparse's SystemExit)
        gc.freeze()
    if isinstance(code, int) and may_skip_teardown(sys._getframe(1).f_globals):
        exit_process(code)
    sys.exit(code)


if __name__ == "__main__":  # pragma: no cover
    console_main()
