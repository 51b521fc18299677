"""The point estimate ``vi`` minimises the expected variation of information (a distance between
label maps, Dahl, Johnson & Mueller 2022), not variational inference: the docs, ``fit --help``
and ``fit``'s closing line said "the VI point estimate", which reads as variational inference's
beside ``--method cavi|svi|vi-gibbs`` and compare-inference's VI methods."""

from __future__ import annotations

import re
from pathlib import Path

from spcopyro.cli.main import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
AMBIGUOUS = re.compile(r"\bVI(/Binder)? (point )?(estimate|loss)|Binder / VI\b")
"""'VI point estimate', 'VI estimate', 'VI loss', 'VI/Binder point estimate', 'Binder / VI'."""


def test_the_docs_never_call_it_the_vi_point_estimate():
    files = [ROOT / "README.md", ROOT / "benchmarks" / "README.md",
             *sorted((ROOT / "docs").rglob("*.md")),
             *sorted((ROOT / "notebooks").glob("*.ipynb"))]  # fmt: skip
    found = [f"{path.relative_to(ROOT)}:{n}: {line.strip()}"
             for path in files
             for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             if AMBIGUOUS.search(line)]  # fmt: skip
    assert not found, "\n".join(found)


def test_fit_help_says_what_vi_is():
    fit = build_parser()._subparsers._group_actions[0].choices["fit"]
    (action,) = [a for a in fit._actions if "--point-estimate" in a.option_strings]
    assert "variation of information (vi" in action.help, action.help
    assert "not variational inference" in action.help, action.help


def test_fits_closing_line_names_the_loss(tmp_path, capsys):
    argv = ["fit", "--out", str(tmp_path / "fit"), "--preset", "original-code", "--sweeps", "20",
            "--marginal-samples", "5", "--point-estimate", "vi", "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "point estimate   vi (expected variation of information " in out, out[-2000:]
