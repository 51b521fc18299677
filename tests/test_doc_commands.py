"""Every command line the documentation shows parses: each ``spcopyro ...`` and
``python benchmarks/X.py ...`` line of a ```bash (or plain) code block and each inline code span
that starts with one, in README.md, benchmarks/README.md and docs/**/*.md, is parsed (never run) by
the real parser -- ``spcopyro.cli.main.build_parser`` or the benchmark's own, caught at its
``parse_args`` -- so a renamed or removed option, or a value the option no longer takes, breaks
the suite. ``fit`` lines also go through the preset's inference defaults and the method's
options (``--method``, ``--method-option``), which the parser leaves as text, and ``ablation
--variant`` and ``compare-inference --iterations`` through the commands' own checks.

Placeholders: an upper-case word (OUT, HOUSE, WORD, DIR) is a string to any path or word option;
the ones an option checks are replaced by :data:`PLACEHOLDERS`. In an inline span (often only a
part of a command) the required options and arguments are optional, ``[--opt V]`` counts as
given, ``[A ...]`` / ``[options]`` and ``...`` are left out (an option followed by ``...`` is only
checked to exist), ``a|b`` is checked once per alternative, and a last option without its
value is only checked to exist."""

from __future__ import annotations

import argparse
import contextlib
import importlib
import io
import re
import shlex
from dataclasses import dataclass
from pathlib import Path

import pytest

from spcopyro.cli.main import attach_negative_coordinates, build_parser

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"
DOCS = [
    ROOT / "README.md",
    ROOT / "benchmarks" / "README.md",
    *sorted((ROOT / "docs").rglob("*.md")),  # docs/ablation/: the reports' "Made by" lines
]
PLACEHOLDERS = {  # a placeholder an option checks -> a value it takes
    "X,Y": "1.5,-2",  # navigate --start
    "COMMAND": "fit",  # spcopyro COMMAND --help
    "P": "paper-dp",  # --preset P
    "N": "3",  # simulate --rooms N
    "H": "40",  # simulate --size H W
    "W": "50",
    "M2": "1",  # show --min-area M2
    "NAME": "cavi",  # fit --method NAME
}
COMMAND_START = ("spcopyro ", "python benchmarks/")


@dataclass(frozen=True)
class DocLine:
    file: str
    line: int
    text: str
    complete: bool  # a code block's line: the whole command, required options included

    def __str__(self) -> str:
        return f"{self.file}:{self.line}: {self.text}"


def doc_lines() -> list[DocLine]:
    """The command lines of the documentation, with their file and line."""
    found = []
    for path in DOCS:
        name = str(path.relative_to(ROOT))
        fence = None  # the open block's language, None outside blocks
        prose: list[tuple[int, str]] = []
        pending = ""  # a block line continued with a backslash
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if line.lstrip().startswith("```"):
                fence = line.strip()[3:].strip() if fence is None else None
                continue
            if fence is None:
                prose.append((number, line))
                continue
            if fence not in ("", "bash"):
                continue
            if line.endswith("\\"):
                pending += line[:-1] + " "
                continue
            line, pending = pending + line, ""
            for part in re.split(r"&&|;|\|", line):
                command = re.sub(r"^(\w+=\S+\s+)+", "", part.strip())  # VAR=value prefixes
                if command.startswith(COMMAND_START):
                    found.append(DocLine(name, number, command, complete=True))
        text = "\n".join(line for _, line in prose)
        for match in re.finditer(r"`([^`\n]*(?:\n[^`\n]+)*)`", text):
            span = " ".join(match.group(1).split())
            if span.startswith(COMMAND_START):
                number = prose[text[: match.start()].count("\n")][0]
                found.append(DocLine(name, number, span, complete=False))
    return found


def _relaxed(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The parser with its required options and arguments made optional (a part of a
    command), recursively into its commands."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for command in action.choices.values():
                _relaxed(command)
        elif action.option_strings:
            action.required = False
        elif action.nargs is None:
            action.nargs = "?"
        elif action.nargs == "+":
            action.nargs = "*"
    return parser


def _tokens(line: DocLine) -> list[list[str]]:
    """The argument lists to parse for one line (several for ``a|b``), placeholders replaced."""
    tokens = shlex.split(line.text, comments=True)
    if not line.complete:
        kept, group = [], None
        for token in tokens:
            if group is not None or token.startswith("["):
                group = [] if group is None else group
                group.append(token.strip("[]"))
                if token.endswith("]"):
                    if group[0].startswith("-"):  # [--opt V]: an option, checked as given
                        kept.extend(group)
                    group = None  # [A ...] or [options]: more of the same, left out
            else:
                kept.append(token)
        tokens = kept
    tokens = [_placeholder(token) for token in tokens]
    choices = [token.split("|") if "|" in token and not token.startswith("-") else [token]
               for token in tokens]  # fmt: skip
    lists = [[]]
    for options in choices:
        lists = [given + [option] for given in lists for option in options]
    return lists


def _placeholder(token: str) -> str:
    """The token with a placeholder replaced (also the value of ``--opt=VALUE``)."""
    if token.startswith("--") and "=" in token:
        name, value = token.split("=", 1)
        return f"{name}={PLACEHOLDERS.get(value, value)}"
    return PLACEHOLDERS.get(token, token)


class _Parsed(Exception):
    """Raised at a benchmark's parse_args with the parser."""


def benchmark_parser(name: str, monkeypatch: pytest.MonkeyPatch) -> argparse.ArgumentParser:
    """The parser ``benchmarks/NAME.py``'s main() builds, caught at its parse_args."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))

    def capture(self, args=None, namespace=None):
        raise _Parsed(self)

    with monkeypatch.context() as patch:
        patch.setattr(argparse.ArgumentParser, "parse_args", capture)
        with pytest.raises(_Parsed) as got:
            importlib.import_module(name).main([])
    return got.value.args[0]


def _option_names(parser: argparse.ArgumentParser, tokens: list[str]) -> dict[str, argparse.Action]:
    """The option strings of the command the tokens name (its own parser's, spelled out)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for token in tokens:
                if token in action.choices:
                    return _option_names(action.choices[token], tokens[tokens.index(token) + 1 :])
    return parser._option_string_actions


def _parse(parser: argparse.ArgumentParser, tokens: list[str]) -> argparse.Namespace | None:
    """Parse, after checking that every option is spelled out in full (no abbreviation) and
    leaving out an option followed by ``...`` or last without its value. None after
    ``--help`` or ``--version``."""
    options = _option_names(parser, tokens)
    kept = []
    for k, token in enumerate(tokens):
        if token == "--":  # the rest are arguments
            kept.extend(tokens[k:])
            break
        if token.startswith("--"):
            name = token.split("=", 1)[0]
            if name not in options:
                raise AssertionError(f"no option {name}")
            following = tokens[k + 1] if k + 1 < len(tokens) else None
            takes_value = options[name].nargs != 0 and "=" not in token
            if takes_value and following in (None, "..."):
                continue  # only named: its name is checked
        if token != "...":
            kept.append(token)
    error = io.StringIO()
    try:
        with contextlib.redirect_stderr(error), contextlib.redirect_stdout(io.StringIO()):
            return parser.parse_args(kept)
    except SystemExit as stop:
        if stop.code:
            raise AssertionError(error.getvalue().strip().splitlines()[-1]) from None
        return None


def _check_fit(args: argparse.Namespace) -> None:
    """What fit does with the arguments before it reads a house: the preset's inference
    defaults, the preset with the model's values, the method and its options."""
    from spcopyro.cli.fit_options import method_options
    from spcopyro.cli.fit_settings import apply_preset_inference
    from spcopyro.config import preset

    apply_preset_inference(args)
    values = {"gamma": args.gamma, "alpha": args.alpha, "beta": args.beta, "chi": args.chi,
              "num_concepts": args.concepts}  # fmt: skip
    preset(args.preset, **{k: v for k, v in values.items() if v is not None})
    method_options(args)


def _check_study_command(args: argparse.Namespace) -> None:
    """``ablation --variant``'s and ``compare-inference --iterations``'s values, which the
    commands read before they run anything."""
    if args.command == "ablation":
        from spcopyro.experiments.ablation_variants import parse_variant

        for text in args.variant or ():
            if text != "...":
                parse_variant(text)
    elif args.command == "compare-inference":
        from spcopyro.experiments.inference_comparison import VARIANTS

        for item in args.iterations or ():
            key, _, value = item.partition("=")
            if key not in VARIANTS or not value.isdigit():
                raise ValueError(f"--iterations {item}: not METHOD=N of {list(VARIANTS)}")


LINES = doc_lines()


def test_the_doc_lines_are_found():
    """The extraction finds the lines it should (a change of the pages' layout would otherwise
    leave this test checking nothing)."""
    texts = {line.text for line in LINES}
    assert len(LINES) >= 200
    assert "spcopyro fit --out out/demo" in texts  # README's first block
    assert any(line.complete and line.file == "benchmarks/README.md" for line in LINES)
    assert "spcopyro where OUT WORD [--prior area|pi] [--out PNG]" in texts  # inline
    assert any("--variant" in text and "orig-g3" in text for text in texts)  # backslash-joined


@pytest.mark.parametrize("line", LINES, ids=str)
def test_the_doc_line_parses(line: DocLine, monkeypatch):
    for tokens in _tokens(line):
        if tokens[0] == "spcopyro":
            parser = build_parser()
            parser = parser if line.complete else _relaxed(parser)
            arguments = attach_negative_coordinates(tokens[1:])
        else:
            parser = benchmark_parser(Path(tokens[1]).stem, monkeypatch)
            parser = parser if line.complete else _relaxed(parser)
            arguments = tokens[2:]
        try:
            args = _parse(parser, arguments)
            if args is not None and getattr(args, "command", None) == "fit":
                _check_fit(args)
            elif args is not None and getattr(args, "command", None):
                _check_study_command(args)
        except (AssertionError, LookupError, ValueError) as error:
            raise AssertionError(f"{line}\n  {' '.join(tokens)}: {error}") from None


@pytest.mark.parametrize(
    ("text", "complete"),
    [
        ("spcopyro fit --out o --sweeeps 3", True),  # an option that does not exist
        ("spcopyro fit --out o --preset bogus", True),  # a value it does not take
        ("spcopyro fit --sweeps 3", True),  # a block's line lacks a required option
        ("spcopyro fit --out o --method bogus", True),  # a method that does not exist
        ("spcopyro fit --out o --method lbp --method-option bogus=1", True),
        ("spcopyro fit --swe 3", False),
        ('spcopyro ablation --out o --variant "sw:preset=paper-dp,bogus=0.2"', True),
        (
            "spcopyro compare-inference --out o --iterations gibbs=2000 bogus=3",
            True,
        ),  # an abbreviation (argparse would take it)
        ("spcopyro where OUT WORD [--prior area|bogus]", False),  # each alternative
        ("python benchmarks/gibbs.py --no-such-option", True),
        ("python benchmarks/footprint.py --presets bogus", False),
    ],
)
def test_a_stale_line_fails(text, complete, monkeypatch):
    """The check can fail: an option renamed, a value refused, a required option missing."""
    with pytest.raises(AssertionError):
        test_the_doc_line_parses(DocLine("x.md", 1, text, complete), monkeypatch)
