"""The compiled sparse loopy-BP backend (spcopyro.guides.numba_lbp) against the dense torch
reference (spcopyro.guides.lbp): messages, beliefs, labels and the Bethe trace after k outer
iterations without truncation; the truncation and active set within reach of it; the backend
selection, with and without numba."""

from __future__ import annotations

import sys

import numpy as np
import pytest
import torch
from gibbs_problems import config, random_problem

from spcopyro.config import preset
from spcopyro.fit.house import prepare_model_data
from spcopyro.guides.lbp_method import LBPOptions, init, resolve_lbp_backend, run_lbp, step
from spcopyro.guides.run import initial_q
from spcopyro.synthetic import HouseSpec, make_house

try:  # the compiled backend is the fast extra's; the reference's tests run without it
    from spcopyro.guides import numba_lbp, numba_lbp_pass
except ImportError:
    numba_lbp = numba_lbp_pass = None
needs_numba = pytest.mark.skipif(numba_lbp is None, reason="numba is not installed (.[fast])")

EXACT = dict(support=0, threshold=0.0, active_tolerance=0.0)  # no truncation, no skipping


pytestmark = pytest.mark.usefixtures("one_torch_thread")  # small tensors


def small_house():
    """A 40 x 50 three-room house at L = 6 (1,299 free cells, observed ones in every room)."""
    house = make_house(seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=3))
    settings = preset("original-code", gamma=2.0, num_concepts=6)
    return prepare_model_data(house, settings)[1], settings.model


PROBLEMS = {
    "grid4": lambda: (random_problem(2, num_observed=8)[1], config(num_concepts=5, gamma=2.5)),
    "grid8": lambda: (
        random_problem(3, connectivity=8, num_observed=8)[1],
        config(num_concepts=5, gamma=0.8),
    ),
    "house": small_house,
}


def iterate(data, cfg, options: LBPOptions, iterations: int, anneal: int = 0):
    """``iterations`` outer iterations from a soft random start, gamma annealed over
    ``anneal``; returns (state, objectives, concepts in use)."""
    q = initial_q(data, cfg, torch.Generator().manual_seed(0), init="soft")
    state = init(q, data, cfg, options)
    objectives, used = [], []
    for k in range(iterations):
        gamma = cfg.gamma * min(1.0, (k + 1) / anneal) if anneal else cfg.gamma
        state, info = step(state, data, cfg, gamma, options)
        objectives.append(info.objective)
        used.append(info.num_concepts)
    return state, np.array(objectives), used


def dense_of(state) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(log messages [N, D, L], beliefs [N, L], labels [N]) of either backend's state."""
    bp = state.bp
    if hasattr(bp, "incoming_total"):  # the reference's LoopyBP
        beliefs = bp.beliefs(bp.h)
        return bp.log_messages, beliefs, beliefs.argmax(-1)
    return bp.log_messages, bp.beliefs(), bp.labels()


@needs_numba
@pytest.mark.parametrize("name", list(PROBLEMS))
@pytest.mark.parametrize("damping", [0.0, 0.5])
def test_numba_equals_the_torch_reference_without_truncation(name, damping):
    """Messages, beliefs, argmax labels, the Bethe trace and the concepts in use after 5 outer
    iterations (gamma annealed over the first 3: the coupling changes between passes)."""
    data, cfg = PROBLEMS[name]()
    runs = {}
    for backend in ("torch", "numba"):
        options = LBPOptions(backend=backend, damping=damping, **EXACT)
        runs[backend] = iterate(data, cfg, options, 5, anneal=3)
    (reference, ref_objective, ref_used), (compiled, objective, used) = runs["torch"], runs["numba"]
    assert type(compiled.bp).__name__ == "SparseLoopyBP"
    ref_messages, ref_beliefs, ref_labels = dense_of(reference)
    messages, beliefs, labels = dense_of(compiled)
    torch.testing.assert_close(messages, ref_messages, rtol=0, atol=1e-11)
    torch.testing.assert_close(beliefs, ref_beliefs, rtol=0, atol=1e-11)
    torch.testing.assert_close(labels, ref_labels)
    np.testing.assert_allclose(objective, ref_objective, rtol=1e-11)
    assert used == ref_used
    torch.testing.assert_close(compiled.factors.pi, reference.factors.pi, rtol=1e-11, atol=0)


@needs_numba
def test_the_statistics_and_objective_are_those_of_the_dense_beliefs():
    """The sparse summaries (sizes, observed q, Bethe terms) against the reference's formulas
    applied to the compiled backend's own dense beliefs and messages, with truncation on."""
    from spcopyro.guides.lbp import LoopyBP, bethe_objective
    from spcopyro.likelihood import concept_statistics

    data, cfg = small_house()
    options = LBPOptions(backend="numba", support=3, threshold=1e-3, active_tolerance=1e-3)
    state, _, _ = iterate(data, cfg, options, 4)
    bp = state.bp
    beliefs = bp.beliefs()
    statistics = concept_statistics(beliefs, data, cfg)
    torch.testing.assert_close(bp.statistics().cells, statistics.cells, rtol=1e-10, atol=1e-9)
    for mine, theirs in zip(bp.statistics().counts, statistics.counts, strict=True):
        torch.testing.assert_close(mine, theirs, rtol=1e-10, atol=1e-9)
    reference = LoopyBP(data, cfg)
    reference.log_messages.copy_(bp.log_messages)
    reference.gamma = bp.gamma
    # the last pass's node potentials, up to a constant a cell (which the beliefs ignore): the
    # base rows beta = exp(h - max h)
    reference.h = torch.from_numpy(np.log(bp._tables[0]))[torch.from_numpy(bp.rows)]  # [N, L]
    torch.testing.assert_close(reference.beliefs(reference.h), beliefs, rtol=0, atol=1e-12)
    expected = float(bethe_objective(reference, state.factors, data, cfg))
    assert bp.objective(state.factors) == pytest.approx(expected, rel=1e-10)


@needs_numba
@pytest.mark.parametrize("changes", [{}, {"threshold": 1e-2}, {"active_tolerance": 1e-2}])
def test_truncation_and_the_active_set_stay_close_to_the_reference(changes):
    """The defaults (threshold 1e-4, tolerance 1e-3), a coarser threshold and a coarser
    tolerance after 12 iterations: beliefs within 0.01 of the untruncated run's (measured
    4e-5, 4e-3, 7e-4), the same argmax labels, the Bethe objective within 2e-5 of it (measured
    1e-5)."""
    data, cfg = small_house()
    exact, exact_objective, _ = iterate(data, cfg, LBPOptions(backend="numba", **EXACT), 12)
    cut, objective, _ = iterate(data, cfg, LBPOptions(backend="numba", **changes), 12)
    assert float((cut.bp.beliefs() - exact.bp.beliefs()).abs().max()) < 0.01
    torch.testing.assert_close(cut.bp.labels(), exact.bp.labels())
    assert objective[-1] == pytest.approx(exact_objective[-1], rel=2e-5)
    assert cut.bp.sent_cells < exact.bp.sent_cells  # the active set skipped some cells


@needs_numba
def test_capped_messages_stay_normalised():
    """support = 3: at most 3 excess entries a message, every dense message normalised."""
    data, cfg = small_house()
    state, objective, _ = iterate(data, cfg, LBPOptions(backend="numba", support=3), 4)
    messages = state.bp.log_messages[data.neighbours >= 0]  # [E, L]
    torch.testing.assert_close(torch.logsumexp(messages, -1),
                               torch.zeros(len(messages), dtype=messages.dtype))  # fmt: skip
    assert state.bp.cnt.max() <= 3 and np.isfinite(objective).all()


@needs_numba
def test_the_active_set_stops_the_passes_at_a_fixed_point():
    """At fixed globals the damped messages settle: with a tolerance of 1e-9 every cell is
    eventually skipped, and the beliefs are then those of more passes without skipping."""
    data, cfg = small_house()
    options = LBPOptions(backend="numba", support=0, threshold=0.0, active_tolerance=1e-9)
    state, _, _ = iterate(data, cfg, options, 3)
    bp = state.bp
    for _ in range(300):  # the same globals: the messages settle to their fixed point
        bp.run(state.factors, cfg.gamma)
        if bp.sent_cells == 0:
            break
    assert bp.sent_cells == 0
    settled = bp.beliefs()
    bp.active_tolerance = 0.0
    bp.drift[:] = np.inf  # every cell sends again
    bp.run(state.factors, cfg.gamma)
    assert float((bp.beliefs() - settled).abs().max()) < 1e-7


def excesses(bp) -> np.ndarray:
    """[N * D, L] every stored message's excess rho, dense (0 outside its entries)."""
    E, K = bp.idx.shape
    dense = np.zeros((E, bp.config.num_concepts))
    live = np.arange(K)[None, :] < bp.cnt[:, None]  # [E, K]
    dense[np.nonzero(live)[0], bp.idx[live]] = bp.val[live]
    return dense


def _passes_until_one_skips(damping: float, support: int, threshold: float):
    """(data, cfg, state, bp) of the small house after 3 outer iterations and then single
    passes under the same globals until the active set skips a cell (1-10 passes)."""
    data, cfg = small_house()
    options = LBPOptions(backend="numba", damping=damping, passes=1, support=support,
                         threshold=threshold, active_tolerance=1e-2)  # fmt: skip
    state, _, _ = iterate(data, cfg, options, 3)
    bp = state.bp
    for _ in range(20):
        bp.run(state.factors, cfg.gamma)
        if bp.sent_cells < data.num_free:
            break
    return data, cfg, state, bp


@needs_numba
@pytest.mark.parametrize("damping", [0.0, 0.5])
@pytest.mark.parametrize("support", [0, 3])
def test_each_message_records_how_far_it_moved(damping, support):
    """One pass's ``moved`` of every message against its definition applied to the stored
    excesses before and after: half the log range over l of (1 + rho_new) / (1 + rho_old), the
    range taken with 1 in it (0 for a skipped sender, whose message stays), on each of the
    pass's paths: undamped and damped, with a cap (support 3: the top-K cut after damping) and
    without; and the logs stored with the message, log(1 + rho)."""
    data, cfg, state, bp = _passes_until_one_skips(damping, support, threshold=1e-3)
    before = excesses(bp)
    bp.run(state.factors, cfg.gamma)
    after = excesses(bp)
    change = np.log1p(after) - np.log1p(before)  # [E, L]
    expected = 0.5 * (np.maximum(change.max(1), 0.0) - np.minimum(change.min(1), 0.0))
    live = (data.neighbours >= 0).numpy().reshape(-1)  # [E] the messages that exist
    assert 0 < bp.sent_cells < data.num_free  # some cells sent, some were skipped
    np.testing.assert_allclose(bp.moved[live], expected[live], rtol=1e-9, atol=1e-12)
    live_entries = np.arange(bp.idx.shape[1])[None, :] < bp.cnt[:, None]
    np.testing.assert_allclose(bp.lg[live_entries], np.log1p(bp.val[live_entries]), rtol=1e-14)


MESSAGES = ("idx", "val", "lg", "cnt", "msum", "moved", "drift", "residual", "belief_drift")


@needs_numba
@pytest.mark.parametrize("damping", [0.0, 0.5])
@pytest.mark.parametrize("support", [0, 3])
def test_each_cell_records_how_far_damping_left_its_messages(damping, support):
    """One pass's ``residual`` of every cell against its definition (the module docstring):
    the largest over its messages of half the log range over l of (1 + rho_stored) / (1 +
    rho_undamped), the range taken with 1 in it; 0 undamped, kept by a skipped cell. The
    undamped messages are the pass's own at damping 0 from what the cell saw: the pass replayed
    cell by cell in its order (which reproduces it), each sender also sent undamped from a copy.
    On the damped paths with a cap (support 3: the top-K cut after damping, where the range is
    measured again over what is kept) and without."""
    # threshold 3e-2: damping takes some undamped entries below it (their own path)
    data, cfg, state, bp = _passes_until_one_skips(damping, support, threshold=3e-2)
    replay = {name: getattr(bp, name).copy() for name in MESSAGES}
    bp.run(state.factors, cfg.gamma)  # the same globals: no base row drifted
    beta, _, border, bsum, _ = bp._tables
    D, L = bp.nb.shape[1], cfg.num_concepts

    def send(arrays: dict, cell: int, damping: float) -> int:
        return numba_lbp_pass._message_pass(
            *(arrays[name] for name in MESSAGES), np.array([cell]), bp.nb, bp.rev, bp.rows,
            beta, border, bsum, np.zeros(len(bsum)), float(cfg.gamma), bp.threshold, damping,
            bp.active_tolerance, np.zeros(L, np.int64), np.zeros(L, np.int64),
            np.zeros((D, L), np.int64), np.zeros(L), np.zeros(L), np.zeros((D, L)),
        )  # fmt: skip

    def rows_of(arrays: dict, rows: np.ndarray) -> np.ndarray:
        """[len(rows), L] those stored messages' excesses, dense."""
        dense = np.zeros((len(rows), L))
        for k, e in enumerate(rows):
            dense[k, arrays["idx"][e, : arrays["cnt"][e]]] = arrays["val"][e, : arrays["cnt"][e]]
        return dense

    expected = replay["residual"].copy()  # [N]
    for i in bp.order:
        undamped = {name: array.copy() for name, array in replay.items()}
        undamped["drift"][i] = np.inf  # sends
        send(undamped, i, 0.0)
        if send(replay, i, damping) == 0:
            continue  # skipped: its residual stays
        live = bp.nb[i] >= 0
        out = bp.nb[i, live] * D + bp.rev[i, live]  # [d_i] the messages i sent
        change = np.log1p(rows_of(replay, out)) - np.log1p(rows_of(undamped, out))  # [d_i, L]
        expected[i] = 0.5 * (np.maximum(change.max(1), 0.0) - np.minimum(change.min(1), 0.0)).max()
    for name in ("idx", "val", "cnt", "residual"):  # the replay is the pass
        np.testing.assert_array_equal(replay[name], getattr(bp, name))
    assert 0 < bp.sent_cells < data.num_free  # some cells sent, some were skipped
    np.testing.assert_allclose(bp.residual, expected, rtol=1e-9, atol=1e-12)
    assert (bp.residual > 0).any() if damping else (bp.residual == 0).all()


def test_backend_selection():
    data, cfg = PROBLEMS["grid4"]()
    assert resolve_lbp_backend(LBPOptions(backend="torch"), data, cfg) == "torch"
    expected = "torch" if numba_lbp is None else "numba"
    assert resolve_lbp_backend(LBPOptions(), data, cfg) == expected
    strong = config(num_concepts=4, gamma=150.0)  # gamma D = 600 > 300: products could overflow
    assert resolve_lbp_backend(LBPOptions(), data, strong) == "torch"
    if numba_lbp is not None:
        with pytest.raises(ValueError, match="gamma"):
            init(initial_q(data, strong, torch.Generator()), data, strong,
                 LBPOptions(backend="numba"))  # fmt: skip
    for field, value in [("backend", "gpu"), ("support", -1), ("threshold", -0.1),
                         ("active_tolerance", float("nan"))]:  # fmt: skip
        with pytest.raises(ValueError, match=f"LBPOptions.{field}="):
            LBPOptions(**{field: value})


def test_without_numba_auto_runs_the_torch_reference(monkeypatch):
    """With numba missing (its module unimportable) ``auto`` runs the reference, ``numba``
    raises ImportError."""
    monkeypatch.setitem(sys.modules, "spcopyro.guides.numba_lbp", None)
    data, cfg = PROBLEMS["grid4"]()
    assert resolve_lbp_backend(LBPOptions(), data, cfg) == "torch"
    q = initial_q(data, cfg, torch.Generator().manual_seed(0))
    run, bp = run_lbp(data, cfg, 3, q=q, progress=False)
    assert type(bp).__name__ == "LoopyBP" and np.isfinite(run.objective).all()
    with pytest.raises(ImportError):
        resolve_lbp_backend(LBPOptions(backend="numba"), data, cfg)
