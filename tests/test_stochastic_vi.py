"""Memoized VI on spatial blocks (``stochastic-vi``): exact memo, equal to CAVI with one block,
monotone ELBO, blocks recovered from the neighbour table, a high ARI, clear errors."""

from __future__ import annotations

import logging

import numpy as np
import pytest
import torch

from spcopyro.config import preset
from spcopyro.fit import registry
from spcopyro.fit.house import prepare_model_data
from spcopyro.guides import memoized as stochastic
from spcopyro.guides.blocks import (
    cell_coordinates,
    grid_blocks,
    make_blocks,
    tile_ids,
)
from spcopyro.guides.elbo import elbo
from spcopyro.guides.memoized import (
    Memo,
    StochasticOptions,
    compact_initial_q,
    exact_elbo,
    local_step,
    run_stochastic,
    start_state,
)
from spcopyro.guides.options import VariationalOptions
from spcopyro.guides.run import initial_q, run_variational
from spcopyro.likelihood import concept_statistics
from spcopyro.maps.grid import OccupancyGrid
from spcopyro.metrics import adjusted_rand_index
from spcopyro.synthetic import HouseSpec, make_house

pytestmark = pytest.mark.usefixtures("one_torch_thread")  # small tensors


def _start(data, config, dtype=torch.float64, seed=0):
    return compact_initial_q(data, config, torch.Generator().manual_seed(seed), dtype=dtype)


# --------------------------------------------------------------------------------------------
# Blocks
# --------------------------------------------------------------------------------------------


def _two_rooms() -> OccupancyGrid:
    """Two walled-off rooms (two components) and a lone free cell: a 9 x 12 map."""
    occupancy = np.full((9, 12), 100)
    occupancy[1:5, 1:6] = 0
    occupancy[2:8, 7:11] = 0
    occupancy[7, 2] = 0
    return OccupancyGrid(occupancy=occupancy, resolution=0.1, origin=(0.0, 0.0, 0.0))


@pytest.mark.parametrize("connectivity", [4, 8])
def test_cell_coordinates_are_the_grid_cells_up_to_a_shift_per_component(
    memoized_house, connectivity
):
    house = memoized_house[0]
    for grid in (house.grid, _two_rooms()):
        found = cell_coordinates(grid.neighbour_table(connectivity))  # [N, 2]
        truth = grid.free_cells  # [N, 2]
        shift = truth - found
        # One shift per component: cells joined by an edge share it.
        pairs = grid.neighbour_pairs(connectivity)
        assert (shift[pairs[:, 0]] == shift[pairs[:, 1]]).all()
        assert found.min() == 0
        if grid is house.grid:
            assert (shift == shift[0]).all()  # one component
        else:
            assert len(np.unique(shift, axis=0)) >= 2


def test_a_table_that_is_not_a_grids_is_refused():
    table = torch.tensor([[-1, 1, -1, -1], [-1, -1, 0, -1]])  # 0 above 1, but 1 right of 0
    with pytest.raises(ValueError, match="not a grid's"):
        cell_coordinates(table)
    with pytest.raises(ValueError, match=r"\[N, 4\] or \[N, 8\]"):
        cell_coordinates(torch.zeros(3, 5, dtype=torch.long))


def test_blocks_are_tiles_that_partition_the_cells_by_colour(memoized_house):
    house, data, _ = memoized_house
    blocks = grid_blocks(data, 7)
    order = blocks.order.numpy()
    assert np.array_equal(np.sort(order), np.arange(data.num_free))
    rows, cols = house.grid.free_cells.T
    for b in range(blocks.num_blocks):
        cells = blocks.cells(b).numpy()
        assert (rows[cells].max() - rows[cells].min()) < 7
        assert (cols[cells].max() - cols[cells].min()) < 7
        assert (blocks.block_of[cells] == b).all()
        for c, colour in enumerate(data.colours):
            part = order[int(blocks.starts[b, c]) : int(blocks.starts[b, c + 1])]
            assert np.isin(part, colour.numpy()).all()
    # The tiles of the true coordinates (one component, shifted to start at 0).
    shifted = house.grid.free_cells - house.grid.free_cells.min(0)
    assert np.array_equal(tile_ids(shifted, 7), blocks.block_of.numpy())


def test_bad_block_ids_are_refused(memoized_house):
    data = memoized_house[1]
    with pytest.raises(ValueError, match="block ids must be"):
        make_blocks(data, np.zeros(data.num_free - 1, dtype=np.int64))
    ids = np.zeros(data.num_free, dtype=np.int64)
    ids[0] = 2  # id 1 unused
    with pytest.raises(ValueError, match="every id"):
        make_blocks(data, ids)
    with pytest.raises(ValueError, match="block size"):
        tile_ids(np.zeros((3, 2), dtype=np.int64), 0)


# --------------------------------------------------------------------------------------------
# The memo and the ELBO
# --------------------------------------------------------------------------------------------


def _assert_memo_exact(memo: Memo, q: torch.Tensor, data, config) -> None:
    """Sums and every block's memo equal a full recomputation from the current q."""
    full = concept_statistics(q.to(torch.float64), data, config)
    torch.testing.assert_close(memo.total_cells, full.cells, rtol=1e-9, atol=1e-9)
    for total, counts in zip(memo.total_counts, full.counts, strict=True):
        torch.testing.assert_close(total, counts, rtol=1e-9, atol=1e-9)
    for b in range(memo.blocks.num_blocks):
        cells = memo.blocks.cells(b)
        torch.testing.assert_close(memo.cells[b], q[cells].to(torch.float64).sum(0))


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_memo_always_equals_the_full_recomputation_and_the_elbo_rises_every_step(
    memoized_house, dtype
):
    _, data, config = memoized_house
    q = _start(data, config, dtype)
    options = StochasticOptions(block_size=9)
    state = start_state(data, config, q, options)
    _assert_memo_exact(state.memo, q, data, config)
    generator = torch.Generator().manual_seed(3)
    previous = -np.inf
    for step in range(3 * state.blocks.num_blocks):
        size = 1 + step % 3
        batch = torch.randperm(state.blocks.num_blocks, generator=generator)[:size].tolist()
        local_step(q, state.factors, data, config, state.blocks, batch, config.gamma, state.rows)
        for block in batch:
            state.memo.replace(q, block)
        _assert_memo_exact(state.memo, q, data, config)  # before any re-summing
        factors = stochastic.update_factors(state.memo.statistics(), data, config)
        state = state._replace(factors=factors)  # the state is a NamedTuple
        value = exact_elbo(q, state.factors, state.memo.statistics(), data, config)
        slack = 1e-9 if dtype == torch.float64 else 1e-5
        assert value >= previous - slack * abs(value), step
        previous = value


def test_exact_elbo_equals_the_dense_elbo(memoized_house, monkeypatch):
    _, data, config = memoized_house
    monkeypatch.setattr(stochastic, "CHUNK", 37)  # many chunks, a ragged last one
    q = torch.softmax(torch.randn(data.num_free, config.num_concepts, dtype=torch.float64), -1)
    state = start_state(data, config, q, StochasticOptions(block_size=10))
    dense = float(elbo(q, state.factors, data, config))
    chunked = exact_elbo(q, state.factors, state.memo.statistics(), data, config)
    assert chunked == pytest.approx(dense, rel=1e-12)


def test_the_run_keeps_the_memo_exact_after_every_pass(memoized_house):
    _, data, config = memoized_house
    seen = []

    def check(sweep, state):
        _assert_memo_exact(state.memo, state.q, data, config)
        seen.append(sweep)

    q = _start(data, config, torch.float32)
    options = StochasticOptions(block_size=12, blocks_per_step=2, local_sweeps=2)
    run_stochastic(data, config, 3, q=q, generator=torch.Generator().manual_seed(0),
                   options=options, progress=False, callback=check)  # fmt: skip
    assert seen == [0, 1, 2]


# --------------------------------------------------------------------------------------------
# Against CAVI, and monotone
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("pi_family", ["dirichlet", "stick-breaking"])
def test_one_block_covering_the_map_is_full_batch_cavi(memoized_house, pi_family):
    _, data, config = memoized_house
    cavi_q = initial_q(data, config, torch.Generator().manual_seed(5))
    # numba CAVI's defaults truncate (threshold 1e-4) and skip cells that moved little (active
    # set): both off here, where every cell's exact update is compared
    cavi_options = VariationalOptions(anneal_iterations=3, pi_family=pi_family, threshold=0.0,
                                      active_tolerance=0.0)  # fmt: skip
    cavi = run_variational(data, config, 8, q=cavi_q, options=cavi_options, progress=False)
    q = _start(data, config, torch.float64, seed=5)
    assert torch.equal(q, initial_q(data, config, torch.Generator().manual_seed(5)))
    options = StochasticOptions(block_size=10_000, anneal_passes=3, pi_family=pi_family,
                                dtype="float64")  # fmt: skip
    memo = run_stochastic(data, config, 8, q=q, generator=torch.Generator(), options=options,
                          progress=False)  # fmt: skip
    np.testing.assert_allclose(memo.objective, cavi.objective, rtol=1e-10)
    np.testing.assert_allclose(memo.gammas, cavi.gammas)
    torch.testing.assert_close(memo.q, cavi.q, rtol=0, atol=1e-9)
    torch.testing.assert_close(memo.factors.pi, cavi.factors.pi, rtol=1e-10, atol=1e-9)


@pytest.mark.parametrize(
    "options",
    [
        StochasticOptions(block_size=8, dtype="float64"),
        StochasticOptions(block_size=8, blocks_per_step=3, order="raster", dtype="float64"),
        StochasticOptions(block_size=13, local_sweeps=3, pi_family="stick-breaking",
                          dtype="float64"),
        StochasticOptions(block_size=8),  # float32
    ],
)  # fmt: skip
def test_the_elbo_never_decreases_from_pass_to_pass(memoized_house, options):
    _, data, config = memoized_house
    q = _start(data, config, torch.float64 if options.dtype == "float64" else torch.float32)
    run = run_stochastic(data, config, 12, q=q, generator=torch.Generator().manual_seed(2),
                         options=options, progress=False)  # fmt: skip
    slack = 1e-9 if options.dtype == "float64" else 1e-5
    assert np.diff(run.objective).min() >= -slack * np.abs(run.objective).max()
    assert run.objective[-1] > run.objective[0]


def test_a_high_ari_on_an_easy_house_through_the_registry():
    logging.disable(logging.WARNING)
    house = make_house(seed=0, spec=HouseSpec(images_per_room_per_trial=30, num_open_plan=0))
    settings = preset("original-code", num_concepts=20, gamma=2.1)
    _, data = prepare_model_data(house, settings)
    logging.disable(logging.NOTSET)
    method = registry.get_method("stochastic-vi")
    options = StochasticOptions(block_size=16, blocks_per_step=4, anneal_passes=10)
    output = method.run(data, settings.model, iterations=25, options=options,
                        generator=torch.Generator().manual_seed(0), progress=False)  # fmt: skip
    labels = np.full(house.grid.shape, -1)
    labels[house.grid.free] = output.labels
    assert adjusted_rand_index(labels, house.truth) > 0.85
    assert output.marginals.dtype == np.float32
    assert output.marginals.shape == (data.num_free, 20)
    np.testing.assert_allclose(output.marginals.sum(-1), 1.0, atol=1e-5)
    assert output.trace.objective_name == "ELBO" and len(output.trace.objective) == 25
    assert output.options["block_size"] == 16 and output.options["iterations"] == 25
    np.testing.assert_allclose(output.pi.sum(), 1.0)


def test_fit_house_and_the_cli_run_stochastic_vi(tmp_path):
    import json

    from spcopyro.cli.main import main
    from spcopyro.fit.house import fit_house

    house = make_house(seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3))
    settings = preset("original-code", gamma=3.0, num_concepts=8)
    options = StochasticOptions(block_size=12, anneal_passes=3)
    result = fit_house(house, settings, method="stochastic-vi", options=options, sweeps=8,
                       progress=False)  # fmt: skip
    assert result.method == "stochastic-vi" and result.marginals.shape == (house.grid.num_free, 8)
    assert result.trace.objective_name == "ELBO" and len(result.trace.objective) == 8
    answer = result.where(result.vocabulary[0])
    assert answer.region.sum() > 0
    out = tmp_path / "fit"
    args = ["fit", "--out", str(out), "--method", "stochastic-vi", "--sweeps", "3",
            "--preset", "original-code", "--gamma", "3", "--concepts", "8"]  # fmt: skip
    assert main(args) == 0
    saved = json.loads((out / "config.json").read_text())
    assert saved["method"] == "stochastic-vi" and saved["inference"]["iterations"] == 3
    assert saved["inference"]["block_size"] == StochasticOptions().block_size
    # config.json names the backend that ran, as CAVI's and LBP's do (auto resolved)
    expected = "torch" if stochastic.compiled_path("auto") is None else "numba"
    assert saved["inference"]["backend_used"] == expected
    torch_only = fit_house(house, settings, method="stochastic-vi", sweeps=2, progress=False,
                           options=StochasticOptions(backend="torch"))  # fmt: skip
    assert torch_only.inference["backend_used"] == "torch"


# --------------------------------------------------------------------------------------------
# Errors
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        (dict(block_size=0), "block_size"),
        (dict(block_size=2.5), "block_size"),
        (dict(blocks_per_step=0), "blocks_per_step"),
        (dict(local_sweeps=True), "local_sweeps"),
        (dict(order="spiral"), "order"),
        (dict(anneal_passes=-1), "anneal_passes"),
        (dict(pi_family="pitman-yor"), "pi_family"),
        (dict(tolerance=-1e-3), "tolerance"),
        (dict(tolerance=float("nan")), "tolerance"),
        (dict(dtype="float16"), "dtype"),
    ],
)
def test_bad_options_name_the_field(changes, field):
    with pytest.raises(ValueError, match=rf"StochasticOptions\.{field}="):
        StochasticOptions(**changes)


def test_bad_arguments_give_clear_errors(memoized_house):
    _, data, config = memoized_house
    q = _start(data, config)
    generator = torch.Generator()
    with pytest.raises(ValueError, match="passes must be an integer >= 1"):
        run_stochastic(data, config, 0, q=q, generator=generator, progress=False)
    with pytest.raises(TypeError, match="StochasticOptions"):
        run_stochastic(data, config, 1, q=q, generator=generator, progress=False,
                       options=VariationalOptions())  # fmt: skip
    with pytest.raises(ValueError, match="q must be"):
        run_stochastic(data, config, 1, q=q[:-1], generator=generator, progress=False)
    other = make_blocks(data, np.zeros(data.num_free, dtype=np.int64))._replace(
        block_of=torch.zeros(3, dtype=torch.long)
    )
    with pytest.raises(ValueError, match="blocks were made for 3 cells"):
        run_stochastic(data, config, 1, q=q, generator=generator, blocks=other, progress=False)
    with pytest.raises(ValueError, match="probability vectors"):
        compact_initial_q(data, config, generator, init_q=2 * q)
    with pytest.raises(ValueError, match="init_q must be"):
        compact_initial_q(data, config, generator, init_q=q[:, :2])
    with pytest.raises(ValueError, match="initial labels must lie"):
        compact_initial_q(data, config, generator,
                          init_labels=torch.full((data.num_free,), 99))  # fmt: skip
    with pytest.raises(TypeError, match="stochastic-vi takes StochasticOptions"):
        registry.get_method("stochastic-vi").run(
            data, config, iterations=1, generator=generator, options=VariationalOptions()
        )


def test_warm_start_from_labels_and_tolerance_stop(memoized_house):
    _, data, config = memoized_house
    labels = torch.zeros(data.num_free, dtype=torch.long)
    q = compact_initial_q(data, config, torch.Generator(), init_labels=labels)
    assert (q[:, 0] == 1).all() and q.dtype == torch.float32
    run = run_stochastic(data, config, 200, q=q, generator=torch.Generator().manual_seed(0),
                         options=StochasticOptions(block_size=16, tolerance=1e-3),
                         progress=False)  # fmt: skip
    assert 2 <= len(run.objective) < 200


@pytest.mark.slow
def test_the_benchmark_runs_quick(tmp_path):
    """``benchmarks/stochastic_vi.py --quick`` runs and writes its JSON (numbers not asserted)."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    path = os.pathsep.join(p for p in (str(root), os.environ.get("PYTHONPATH")) if p)
    out = tmp_path / "stochastic_vi.json"
    done = subprocess.run(
        [sys.executable, str(root / "benchmarks" / "stochastic_vi.py"), "--quick", "--out",
         str(out)],
        capture_output=True, text=True, timeout=600, env={**os.environ, "PYTHONPATH": path},
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(out.read_text())
    assert "full-batch CAVI" in done.stdout and "Large map" in done.stdout
    assert results["large"]["passes"] == 6 and results["large_cavi"]["iterations"] == 2


def test_chunked_coefficients_equal_the_dense_ones(memoized_house, monkeypatch):
    from spcopyro.guides.elbo import multinomial_coefficients

    _, data, config = memoized_house
    monkeypatch.setattr(stochastic, "CHUNK", 2000)  # 9 rows of 205 image classes
    chunked = stochastic.chunked_coefficients(data, config)
    assert float(chunked) == pytest.approx(float(multinomial_coefficients(data, config)), rel=1e-12)


def _chunk_by_chunk_coefficients(data, config) -> float:
    """The coefficients as chunked_coefficients summed them before 2026-12-05: one chunk of
    about CHUNK numbers at a time, through the density at log p = 0."""
    from spcopyro.distributions import multinomial_counts_log_prob

    total = torch.zeros((), dtype=torch.float64)
    for modality in data.modalities:
        if config.uses(modality.name):
            rows = max(1, stochastic.CHUNK // modality.counts.shape[-1])
            for lo in range(0, modality.counts.shape[0], rows):
                counts = modality.counts[lo : lo + rows]
                total += multinomial_counts_log_prob(counts, torch.zeros_like(counts)).sum()
    return float(total)


def _count_data(seed: int = 0):
    """Model data and config stand-ins holding footprint-like real-valued counts: [3001, 205]
    images (most entries nonzero) and [3001, 39] words (most zero), the second unused."""
    from types import SimpleNamespace

    gen = torch.Generator().manual_seed(seed)
    images = torch.rand(3001, 205, generator=gen, dtype=torch.float64) * 7
    images[torch.rand(3001, 205, generator=gen) < 0.02] = 0.0
    words = torch.rand(3001, 39, generator=gen, dtype=torch.float64) * 40
    words[torch.rand(3001, 39, generator=gen) < 0.95] = 0.0
    modalities = [SimpleNamespace(name="images", counts=images),
                  SimpleNamespace(name="words", counts=words),
                  SimpleNamespace(name="unused", counts=images + 1)]  # fmt: skip
    config = SimpleNamespace(uses=lambda name: name != "unused")
    return SimpleNamespace(modalities=modalities), config


@pytest.mark.parametrize("block", [1, 2000, 6 * 2000 + 5, 1 << 22])
def test_chunked_coefficients_are_the_chunk_by_chunk_sum_to_the_bit(monkeypatch, block):
    # Blocks of several chunks (the last one ragged), one chunk, and the default: the same float
    # as summing chunk by chunk, not just close to it.
    data, config = _count_data()
    monkeypatch.setattr(stochastic, "CHUNK", 2000)  # 9 rows of images, 51 of words a chunk
    monkeypatch.setattr(stochastic, "COEFFICIENT_BLOCK", block)
    got = stochastic.chunked_coefficients(data, config)
    assert got.dtype == torch.float64 and got.shape == ()
    assert float(got).hex() == _chunk_by_chunk_coefficients(data, config).hex()


def test_chunked_coefficients_take_many_chunks_a_call(monkeypatch):
    # Each block of chunks is one set of torch calls and one advance (the setup bar): at the
    # default block, 3001 rows of images in 10 calls, not one per chunk of 319 rows.
    data, config = _count_data()
    steps: list[int] = []
    got = stochastic.chunked_coefficients(data, config, advance=steps.append)
    assert float(got).hex() == _chunk_by_chunk_coefficients(data, config).hex()
    assert sum(steps) == stochastic._coefficient_chunks(data, config) == 10 + 2
    assert len(steps) == 2, steps


def test_a_memoized_q_that_ends_near_uniform_is_warned_about(caplog):
    """stochastic-vi annealed from gamma 0 over 20 passes under paper-dp at L = 120 ended at
    q(C) uniform (1.000 of log L, "1 concept in use", ARI 0) without a word, where CAVI and loopy
    BP warn: it warns as they do, naming its own option (anneal_passes); from random one-hot
    labels at full gamma it orders and says nothing."""
    from spcopyro.guides.memoized import StochasticVIInference

    house = make_house(seed=0, spec=HouseSpec.scaled(30, 40, num_rooms=2))
    settings = preset("paper-dp")
    _, data = prepare_model_data(house, settings)

    def said(options) -> list[str]:
        caplog.clear()
        with caplog.at_level("WARNING", logger="spcopyro"):
            StochasticVIInference().run(
                data, settings.model, iterations=30, options=options, progress=False,
                generator=torch.Generator().manual_seed(0),
            )  # fmt: skip
        return [r.getMessage() for r in caplog.records if "ended near uniform" in r.getMessage()]

    (annealed,) = said(StochasticOptions(anneal_passes=20))
    assert annealed.startswith("memoized VI's q(C) ended near uniform"), annealed
    assert "gamma 4 < L / D = 30" in annealed and "Try anneal_passes=0" in annealed
    assert said(StochasticOptions(anneal_passes=0)) == []
