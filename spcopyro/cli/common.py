"""What the ``spcopyro`` commands share: loading DATA, the house summary, argument types.

The argument types raise :class:`argparse.ArgumentTypeError`, so a bad value is reported by
argparse on the command's usage line; :class:`_HelpFormatter` ends every option's help with its
default (``spcopyro COMMAND --help``).
"""

from __future__ import annotations

import argparse
import re
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from spcopyro._util.arguments import integer_at_least as _integer_at_least
from spcopyro._util.messages import plural
from spcopyro._util.threads import AUTO
from spcopyro.config import DataPreparation
from spcopyro.data import (
    House,
    cell_counts,
    find_dataset_root,
    list_houses,
    load_house,
    prepared_cell_counts,
)

if TYPE_CHECKING:
    from spcopyro.data.counts import CellCounts
    from spcopyro.maps import OccupancyGrid
    from spcopyro.results.result import SpCoResult
    from spcopyro.results.saved_vocabulary import SavedVocabulary


def _load(data: str | None, seed: int = 0) -> House:
    if data is None:
        from spcopyro.synthetic import HouseSpec, make_house

        return make_house(seed=seed, spec=HouseSpec.embedded())
    room = Path(data)
    try:
        return load_house(room)
    except FileNotFoundError as error:
        if room.exists() or room.is_symlink():  # a file in it is missing: load_house named it
            raise
        raise FileNotFoundError(f"{error}; {_missing_house_hint(room)}") from None


def _missing_house_hint(room: Path) -> str:
    """What ``fit`` and ``show`` say of a house folder ``room`` that does not exist: the public
    house of its name (``fit room1ldk5`` for ``fit DATASET/room1ldk5``), else how a house folder
    is made (the README's ``spcopyro simulate --out out/data`` writes ``out/data/synthetic``)."""
    try:
        root, unfound = find_dataset_root(), ""
    except FileNotFoundError as error:  # $SPCOPYRO_DATA names no dataset: say so
        root, unfound = None, f" ({error})"
    if root is not None and room.name in list_houses(root):  # a house, not its map/ folder
        return f"did you mean {root / room.name}?"
    parent = room.parent
    if room.name == "synthetic":  # the name simulate writes its house under (no --name)
        return f"`{shlex.join(['spcopyro', 'simulate', '--out', str(parent)])}` writes it"
    where = f" (under {root})" if root is not None else unfound
    return (
        f"give a house folder: one of the public dataset's{where}, or one `spcopyro simulate "
        "--out DIR` writes (DIR/synthetic)"
    )


def figure_file(out: str) -> Path:
    """The file a figure saved as ``out`` is written to, resolved: ``out`` itself, or with
    ``.png`` when it has no suffix (matplotlib adds it)."""
    path = Path(out).resolve()
    return path if path.suffix else path.with_suffix(".png")


def load_robot_map(result: SpCoResult, folder: str) -> tuple[Path, OccupancyGrid] | None:
    """The yaml and grid of the map a coarse fit's grid was coarsened from
    (:func:`~spcopyro._util.outputs.robot_map_of`), for ``navigate`` and ``export --nav2``; None
    for a fit on the map's own cells. A data folder's map (the fallback for a fit older than
    ``robot_map.yaml``) that is not finer than the fit's grid is not one it was coarsened from:
    a fit of a map with cells of 0.2 m (or more) runs on them, and planned and exported on that
    map, named as "the map the fit's cells were coarsened from", one edited since the fit."""
    from spcopyro._util.outputs import ROBOT_MAP_FILE, robot_map_of
    from spcopyro.maps import load_map

    path = robot_map_of(result, folder)
    if path is None:
        return None
    grid = load_map(path)
    fallback = path != Path(folder) / ROBOT_MAP_FILE  # not the copy a coarse fit writes
    return None if fallback and grid.resolution >= result.grid.resolution else (path, grid)


def load_start(folder: str) -> SpCoResult:
    """The fit in ``folder`` as the start of another (``fit --init-from``): a coarse fit's grid
    knows the map it was coarsened from again (its ``robot_map.yaml``), so that it starts a fit
    on the map's own cells with its labels refined to them
    (:func:`spcopyro.fit.starts.result_labels`); ``SpCoResult.load`` alone reads a grid of its
    own, which was refused there as another map."""
    import dataclasses

    from spcopyro.results.result import SpCoResult

    result = SpCoResult.load(folder)
    robot_map = None if result.grid.coarsened_from is not None else load_robot_map(result, folder)
    if robot_map is None:
        return result
    grid = dataclasses.replace(result.grid, coarsened_from=robot_map[1])
    return dataclasses.replace(result, grid=grid)


def load_fit(folder: str, asked: Sequence[str] = ()) -> tuple[SpCoResult, SavedVocabulary]:
    """The fit in ``folder`` with its vocabulary read as the tokenizer reads words now
    (:func:`~spcopyro.results.saved_vocabulary.renormalised_result`: a fit saved by an older
    spcopyro held ``stove.`` and ``TV``, which ``where OUT stove`` never found), and what was
    read so; a warning on stderr names the saved words read as others, once, and which of the
    words ``asked`` about (``where OUT stove.``) are saved words answered for as others
    (:meth:`~spcopyro.results.saved_vocabulary.SavedVocabulary.renamed_note`; pass ``saved``
    to :func:`other_word_note`, which then says nothing more of them)."""
    from spcopyro.results.result import SpCoResult
    from spcopyro.results.saved_vocabulary import renormalised_result

    result, saved = renormalised_result(SpCoResult.load(folder))
    note = saved.renamed_note(asked)
    if note:
        print(f"warning: {folder}: {note}", file=sys.stderr)
    return result, saved


def other_word_note(given: str, looked_up: str, saved: SavedVocabulary | None = None) -> str | None:
    """Why the word answered for, ``looked_up`` (the vocabulary's, as
    :func:`~spcopyro.results.semantic_map.word_key` reads ``given``), is not the word the user
    gave but for case, surrounding spaces and Unicode form; None when it is that word.
    ``where OUT -- -tv`` answered for ``tv`` without a word said: the vocabulary holds no word
    with punctuation at its ends (the data's are read without it), so that is what was looked
    up, and the user is told. None too when ``given`` is a word of the fit's ``saved``
    vocabulary read as ``looked_up`` (:func:`load_fit` said so: ``where OUT stove.`` on a fit
    that saved ``stove.`` was told that ``stove.`` is no word of the vocabulary)."""
    from spcopyro.data.text import fold_word, format_characters

    if fold_word(given.strip()) == fold_word(looked_up):
        return None
    if saved is not None and saved.renamed_as(given) == looked_up:
        return None
    hidden = format_characters(given)  # '\u200bkitchen': name what was invisible
    held = f" (it holds {', '.join(hidden)})" if hidden else ""
    return (
        f"{given!r} is not a word of the vocabulary: read as {looked_up!r}, the word "
        f"without the punctuation (or invisible characters) at its ends, as the data's words "
        f"are read{held}"
    )


def refuse_fit_files(result_dir: str, out: str, targets: list[Path]) -> None:
    """ValueError when one of ``targets`` (the files ``--out OUT`` writes, resolved) is one of
    the fit's own files in ``result_dir`` (its manifest,
    :func:`spcopyro._util.outputs.fit_written`), which it would replace."""
    from spcopyro._util.outputs import fit_written

    folder = Path(result_dir).resolve()
    own = fit_written(folder)
    for target in targets:
        if target.parent == folder and target.name in own:
            raise ValueError(
                f"--out {out}: {target.name}, which it would write, is a file of the fit in "
                f"{result_dir}; choose another name"
            )


def _summary(
    house: House,
    warn: bool = True,
    preparation: DataPreparation | None = None,
) -> str:
    """The house's summary lines; ``warn=False`` when the fit will count (and warn) again,
    ``preparation`` the run's (None: :class:`~spcopyro.config.preparation.DataPreparation`'s
    defaults): the observations are counted under its feature scaling (so a bad count is told under
    the scaling it has there) and placed with its snap distance, as the fit places them (the
    placement line counted them at the default 0.25 m whatever the fit's ``--snap-distance``),
    and with a footprint radius, the cells the footprints reach (the fit's observed cells, as
    ``concepts.json`` counts them) are given beside the cells where observations were
    placed."""
    from spcopyro.maps.free_space import no_free_cell_reason

    prep = DataPreparation() if preparation is None else preparation
    free = house.grid.num_free > 0  # else every observation would be listed unplaced
    counts = cell_counts(
        house.grid, house.observations, source=house.source, warn=warn and free,
        feature_scaling=prep.feature_scaling, snap_distance=prep.snap_distance,
    )  # fmt: skip
    obs = house.observations
    grid, source = house.grid, house.grid.coarsened_from
    of_map = "" if source is None else (
        f" (the model's cells, of the map's {source.height} x {source.width} cells at "
        f"{source.resolution:g} m, {source.num_free} free)"
    )  # fmt: skip
    trials = plural(len(obs.trials), "trial")
    lines = [
        f"house            {house.name}",
        f"map              {grid.height} x {grid.width} cells at {grid.resolution:g} m, "
        f"{grid.num_free} free{of_map}",
        f"images           {obs.num_images} ({obs.num_feature_classes} feature classes) in {trials}"
        if obs.num_images
        else f"images           none (a house of words only) in {trials}",
        f"utterances       {obs.num_utterances}, vocabulary of "
        f"{plural(len(counts.vocabulary), 'word')}"
        if obs.num_utterances
        else f"utterances       none (a house of images only) in {trials}",
    ]
    if free:
        lines += _placement_lines(house, counts, prep)
    else:  # `fit` refuses such a map first (spcopyro.maps.check_free_cells), says why
        lines.append(
            f"no free cell     the map {(source or grid).source or ''} has no free cell, nothing "
            f"to label (spcopyro fit refuses it): {no_free_cell_reason(grid)}"
        )
    if house.category_names:
        n = len(house.category_names)
        lines.append(f"ground truth     {n} categor{'y' if n == 1 else 'ies'}: "
                     + ", ".join(house.category_names))  # fmt: skip
    return "\n".join(lines)


def _placement_lines(house: House, counts: CellCounts, prep: DataPreparation) -> list[str]:
    """:func:`_summary`'s lines of a map with free cells: the observed cells (those the
    footprints reach too, given a footprint radius; words counted at their cell named as the
    data line names them, ``words at cell``) and where the observations were placed."""
    observed = f"{len(counts.cells)} (where observations were placed)"
    if prep.spreads:
        spread = prepared_cell_counts(house.grid, house.observations, prep, source=house.source,
                                      warn=False)  # fmt: skip
        radius, words = prep.footprint_radius, prep.words_radius
        own = at_cell = ""
        if words != radius:  # the data line's branching (fit_summary.data_line)
            own, at_cell = (f", words' {words:g} m", "") if words else ("", " (words at cell)")
        reach = ""
        if prep.footprint_reach_share:
            from spcopyro.cli.fit_summary import reach_cut_text

            cut = reach_cut_text(prep.footprint_reach_radius, prep.footprint_reach_door_width)
            reach = f" and {cut}"
        observed += (f"; {len(spread.cells)} within their {radius:g} m{own} footprints{at_cell}"
                     f"{reach}")  # fmt: skip
    p = counts.placement
    return [
        f"observed cells   {observed}",
        f"placement        images: {p.images_on_free} on free cells, {p.images_snapped} snapped, "
        f"{p.images_unplaced} unplaced; words: {p.words_on_free} on free cells, "
        f"{p.words_snapped} snapped, {p.words_unplaced} unplaced "
        f"(snap distance {p.snap_distance} m){p.scaled_away_note()}",
    ]


_positive_int = _integer_at_least(1)
_non_negative_int = _integer_at_least(0)
FIT_SWEEPS = 5000  # --sweeps of a fit from scratch (the paper's)
UPDATE_SWEEPS = 300  # --sweeps of --update (spcopyro.robot.online.DEFAULT_UPDATE_SWEEPS)


class _Unset(int):
    """A default that behaves as its int and tells itself apart from the same value given on
    the command line (argparse keeps a default that is not a string as it is)."""


MARGINAL_SAMPLES = _Unset(50)
"""``fit --marginal-samples``'s default: 50 label maps, for the methods that sample."""


def given(value: object) -> bool:
    """Whether an option whose default is an :class:`_Unset` was given."""
    return not isinstance(value, _Unset)


def command_line(args: argparse.Namespace) -> list[str]:
    """The command line this run was started with, without the program's name (``main(argv)``
    keeps its ``argv`` in ``args.argv``; else ``sys.argv``)."""
    return list(args.argv if getattr(args, "argv", None) else sys.argv[1:])


FIRST_SWEEP_OUTLIER = 10.0
"""A first sweep slower than this many times the others' pace (and over half a second) is
reported apart: numba compiling its code on a first run, not the sampler's pace."""


def pace(first_seconds: float, total_seconds: float, count: int, unit: str = "sweep") -> str:
    """``"1.62 ms per sweep"`` over ``count`` sweeps that took ``total_seconds``; when the first
    of them (``first_seconds``) took much longer than the rest (:data:`FIRST_SWEEP_OUTLIER`),
    the pace of the rest and the first apart: ``"1.62 ms per sweep after a first of 5.1 s"``."""
    if count > 1:
        rest = (total_seconds - first_seconds) / (count - 1)
        if first_seconds > max(FIRST_SWEEP_OUTLIER * rest, 0.5):
            return f"{1e3 * rest:.2f} ms per {unit} after a first of {first_seconds:.1f} s"
    return f"{1e3 * total_seconds / max(count, 1):.2f} ms per {unit}"


def _sweeps(value: str) -> int | str:
    if value == "auto":
        return value
    try:
        sweeps = int(value)
    except ValueError:
        sweeps = 0
    if sweeps < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer or 'auto', got {value!r}")
    return sweeps


def _chain_workers(value: str) -> int | str:
    """``--chain-workers``: ``auto`` or an integer >= 1."""
    if value == AUTO:
        return value
    try:
        return _positive_int(value)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"must be 'auto' or an integer >= 1, got {value!r}"
        ) from None


def _threads(value: str) -> int | str:
    """``--threads``: ``auto`` or an integer >= 0 (0: torch's own setting)."""
    if value == AUTO:
        return value
    try:
        return _non_negative_int(value)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"must be 'auto' or an integer >= 0 (0: torch's own setting), got {value!r}"
        ) from None


def _concentrations(values: list[str] | None) -> dict[str, float] | None:
    """``NAME=VALUE`` options as a mapping (None when there are none)."""
    if not values:
        return None
    pairs = {}
    for value in values:
        name, sep, number = value.partition("=")
        try:
            pairs[name.strip()] = float(number)
        except ValueError:
            sep = ""
        if not sep or not name.strip():
            raise ValueError(f"--concentration must be NAME=NUMBER, got {value!r}")
    return pairs


def _feature_scaling(value: str | None) -> str | float | None:
    if value is None or value in ("probability", "floor100"):
        return value
    try:
        return float(value)
    except ValueError:
        raise SystemExit(
            f"--feature-scaling must be probability, floor100 or a number, got {value!r}"
        ) from None


_PRESET_DEFAULT = "(default: the --preset's value)"


class _HelpFormatter(argparse.HelpFormatter):
    """Every option's help ends with its default, unless the help already says it: ``(default:
    off)`` for a flag, ``(default: VALUE)`` otherwise (an option whose default is None says in
    its own help what happens without it)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if (
            not action.option_strings
            or action.default in (None, argparse.SUPPRESS)
            or "default" in text.lower()
        ):
            return text
        if action.nargs == 0:  # a flag
            return f"{text} (default: {'on' if action.default else 'off'})"
        return f"{text} (default: %(default)s)"


DASH_WORDS = {"where": ("word", "spcopyro where OUT [options] -- {}"),
              "navigate": ("instruction", "spcopyro navigate OUT --start X,Y [options] -- {}"),
              "export": ("word", "--word={}")}  # fmt: skip
"""The commands that take a word or an instruction (a positional, or export's ``--word``), what
it is called and how one that starts with '-' is given (argparse reads it as an option);
:func:`build_parser <spcopyro.cli.main.build_parser>` sets each one's
:attr:`CommandParser.dash_word`."""
_NEGATIVE_NUMBER = re.compile(r"^-\d+$|^-\d*\.\d+$")  # argparse reads these as values
_REQUIRED = "the following arguments are required: "  # argparse's message


class CommandParser(argparse.ArgumentParser):
    """The ``spcopyro`` parser and its commands' (``add_subparsers`` makes its commands of the
    parser's own class): an :class:`argparse.ArgumentParser` whose usage error for a word or
    instruction that starts with '-' (``spcopyro where OUT -tv``, which argparse reads as an
    unknown option, answering "the following arguments are required: word") says so and how to
    give it (after ``--``, or ``--word=-tv``), through argparse's public hooks alone: it records
    the options :meth:`add_argument` returns and the arguments :meth:`parse_known_args` was
    given, and :meth:`error` reads them. Only an argument list argparse refuses anyway is
    refused; every other error is argparse's own.

    ``dash_word``: ``(dest, how)`` of a command that takes one (:data:`DASH_WORDS`), else None.
    Its options are added with :meth:`add_argument` on the parser itself (an argument group's
    are not recorded)."""

    def __init__(self, *args, **kwargs) -> None:
        self.dash_word: tuple[str, str] | None = None
        self.recorded_options: dict[str, argparse.Action] = {}  # option string -> action
        self.given_arguments: list[str] = []
        super().__init__(*args, **kwargs)  # adds -h through add_argument

    def add_argument(self, *args, **kwargs) -> argparse.Action:  # noqa: D102
        action = super().add_argument(*args, **kwargs)
        for option in action.option_strings:
            self.recorded_options[option] = action
        return action

    def parse_known_args(self, args=None, namespace=None):  # noqa: D102
        self.given_arguments = list(sys.argv[1:] if args is None else args)
        parsed, extras = super().parse_known_args(args, namespace)
        hint = self._dash_word_hint(None) if extras else None
        if hint:  # `export --word bed -tv`: "-tv" among --word's values, not an option
            self.error(hint)
        return parsed, extras

    def error(self, message: str) -> NoReturn:  # noqa: D102
        super().error(self._dash_word_hint(message) or message)

    def _option(self, token: str) -> argparse.Action | None:
        """The recorded option ``token`` names (``--opt=value``, a unique prefix of a long
        option as argparse takes it), else None."""
        name = token.split("=", 1)[0]
        if name in self.recorded_options:
            return self.recorded_options[name]
        if not name.startswith("--"):
            return None
        matches = {a for o, a in self.recorded_options.items() if o.startswith(name)}
        return matches.pop() if len(matches) == 1 else None

    def _dash_word_hint(self, message: str | None) -> str | None:
        """The usage error for a token that starts with '-', is none of the command's options
        (nor a value argparse takes: a negative number, text with a space) and stands where the
        word goes -- the positional word ``message`` says is missing, or among the values of an
        option whose dest is the word (``message`` None: argparse left the token over) -- else
        None (argparse's own message stands)."""
        if self.dash_word is None:
            return None
        what, how = self.dash_word
        missing = message is not None and message.startswith(_REQUIRED) and what in [
            name.strip() for name in message[len(_REQUIRED) :].split(",")
        ]  # fmt: skip
        if message is not None and not missing and not message.startswith("argument --"):
            return None
        current = None  # the option whose values the next tokens are
        for token in self.given_arguments:
            if token == "--":
                return None
            option = self._option(token)
            if option is not None:
                current = option if option.nargs != 0 and "=" not in token else None
                continue
            if not token.startswith("-") or len(token) == 1 or " " in token:
                is_value = True
            else:
                is_value = bool(_NEGATIVE_NUMBER.match(token))
            if is_value:
                if current is not None and current.nargs in (None, 1):
                    current = None  # its one value taken: the next are positionals
                continue
            at_word = current.dest == what if current is not None else missing
            if not at_word:
                return None  # an unknown option elsewhere: argparse says so
            command = self.prog.split()[-1]
            return (
                f"{token!r} is read as an option, and {command} has none of that name; "
                f"{'an' if what[0] in 'aeiou' else 'a'} {what} that starts with '-' is given "
                f"as: {how.format(token)}"
            )
        return None
