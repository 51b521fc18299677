"""The flat-q warning of the variational methods: one function owns the check and the wording
(:func:`spcopyro.guides.run.warn_flat_q`), each method passes its own way out."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import torch

from spcopyro.config import preset
from spcopyro.guides.run import restart_way_out, warn_flat_q
from spcopyro.guides.svi_method import SVIOptions, flat_q_advice
from spcopyro.inference.schedule import short_runs_meant

PACKAGE = Path(__file__).resolve().parents[1] / "spcopyro"
HEAD = (
    "'s q(C) ended near uniform: mean entropy 4.787 nats a cell, 100.0% of log L = 4.787, so "
    "its map is the argmax of nearly flat marginals, close to arbitrary, whatever its concepts "
    "in use ("
)
BELOW = "gamma 4 < L / D = 30: mean field's disordered fixed point holds a start near uniform"
STAYED = "the start stayed in the label update's disordered fixed point"


def said(caplog, *args, **kwargs) -> list[str]:
    caplog.clear()
    with caplog.at_level("WARNING", logger="spcopyro"):
        warned = warn_flat_q(*args, **kwargs)
    messages = [r.getMessage() for r in caplog.records]
    assert warned == bool(messages)
    return messages


def test_one_function_words_the_flat_q_warning():
    """Two functions named warn_flat_q (guides/run.py for CAVI, loopy BP and memoized VI,
    guides/svi_method.py for SVI) each checked q and worded "q(C) ended near uniform" their own
    way; one owns both now."""
    owners = [
        str(path.relative_to(PACKAGE))
        for path in sorted(PACKAGE.rglob("*.py"))
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.FunctionDef) and node.name == "warn_flat_q"
    ]
    assert owners == ["guides/run.py"], owners


def test_the_warning_of_cavi_loopy_bp_and_memoized_vi(caplog):
    """The messages CAVI, loopy BP and memoized VI gave before the warning had one owner, word
    for word (L = 120, gamma 4, D = 4: q uniform)."""
    config = preset("paper-dp").model
    q = torch.full((50, config.num_concepts), 1.0 / config.num_concepts)  # [N, L] uniform
    annealed = restart_way_out(20)
    assert said(caplog, q, config, "CAVI", annealed) == [
        f"CAVI{HEAD}{BELOW}). Try anneal_iterations=0 (fit's --method-option anneal_iterations=0): "
        "it annealed from gamma 0 over 20, inside that point's basin; or a fitted start, e.g. of "
        "a Gibbs fit: init=result (fit's --init-from OUT)"
    ]
    soft = restart_way_out(0, init="soft")
    assert said(caplog, q, config, "CAVI", soft) == [
        f"CAVI{HEAD}{BELOW}). Try init='one-hot' (fit's --method-option init=one-hot): Dir(1) "
        "rows start near uniform; or a fitted start, e.g. of a Gibbs fit: init=result (fit's "
        "--init-from OUT)"
    ]
    assert "init='one-hot'" not in restart_way_out(0, init="soft", warm=True)
    passes = restart_way_out(5, "anneal_passes")
    (memoized,) = said(caplog, q, config, "memoized VI", passes)
    assert memoized.startswith(f"memoized VI{HEAD}{BELOW}). Try anneal_passes=0 "), memoized
    (bp,) = said(caplog, q, config, "loopy BP", annealed, mean_field=False)
    assert bp.startswith(f"loopy BP{HEAD}{STAYED}). Try anneal_iterations=0"), bp
    strong = dataclasses.replace(config, gamma=40.0)
    (above,) = said(caplog, q, strong, "CAVI", annealed)
    assert above.startswith(f"CAVI{HEAD}{STAYED}). Try "), above


def test_the_warning_of_svi(caplog):
    """SVI's parts (its start, the way out that keeps a given start) in the shared wording."""
    config = preset("paper-dp").model
    q = torch.full((50, config.num_concepts), 1.0 / config.num_concepts)  # [N, L] uniform
    context, way_out = flat_q_advice(SVIOptions(), resumed=False, given_start=False)
    assert said(caplog, q, config, "SVI", way_out, context=context) == [
        f"SVI{HEAD}{BELOW}; start: random labels, label_smoothing=0.9, annealed from gamma 0 "
        "over 100 steps; Adam's steps lead there from random labels too: docs/variational.md). "
        "Start from a fitted map, init=result (fit's --init-from OUT) or init_labels (smoothed by "
        "label_smoothing=0.05 and not annealed, anneal_iterations=0, unless they are set), or use "
        "method='cavi' (fit's --method cavi)"
    ]
    context, way_out = flat_q_advice(SVIOptions(label_smoothing=0.9), False, given_start=True)
    assert context.startswith("start: given labels, label_smoothing=0.9; Adam's"), context
    assert way_out == (
        "Keep the given start (label_smoothing=0.05, the default for given labels) or use "
        "method='cavi' (fit's --method cavi)"
    )
    assert flat_q_advice(SVIOptions(), True, given_start=True)[0].startswith(
        "start: the resumed q;"
    )


def test_no_warning_for_an_ordered_q_or_inside_short_runs(caplog):
    config = preset("paper-dp").model
    L = config.num_concepts
    ordered = torch.nn.functional.one_hot(torch.arange(50) % L, L).to(torch.float64)  # [N, L]
    assert said(caplog, ordered, config, "CAVI", restart_way_out(20)) == []
    with short_runs_meant():
        flat = torch.full((50, L), 1.0 / L)  # [N, L]
        assert said(caplog, flat, config, "CAVI", restart_way_out(20)) == []
