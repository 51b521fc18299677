"""The observation footprint (spcopyro.data.footprint, DataPreparation.footprint_*): each
observation spread over the free cells within a geodesic radius, weights summing to one.

Checked: the weights (sum to one, never through a wall or a wall's corner, the kernels, the field
of view), radius 0 equal to the paper's counts exactly, the per-cell counts as the weighted sums,
the Pyro model's density on them as the tempered product of the observations' likelihoods, the
Gibbs conditionals (both backends) and Dirichlet posterior counts under the footprint, CAVI's ELBO
rising, and the switch from ``preset`` and ``spcopyro fit --footprint``.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch
from benchmark_setup import run_benchmark
from gibbs_problems import config, tiny_grid
from scipy import stats
from statistical_checks import assert_conditionals_match_model, backend_samplers, model_log_density

from spcopyro.cli.main import main
from spcopyro.config import DataPreparation, preset
from spcopyro.data import ModalityObservations, Observations, cell_counts, place_observations
from spcopyro.data.footprint import footprint_weights, free_cell_graph, spread_counts
from spcopyro.distributions import multinomial_counts_log_prob
from spcopyro.gibbs.sampler import init
from spcopyro.gibbs.state import make_sweep_plan
from spcopyro.gibbs.sweep import label_log_conditionals
from spcopyro.guides.options import VariationalOptions
from spcopyro.guides.run import initial_q, run_variational
from spcopyro.likelihood import concept_statistics
from spcopyro.model import make_model_data

# 0.1 m cells, origin (0, 0): a wall down column 5 with a doorway in row 5 (the bottom row)
ROWS = [
    ".....#....",
    ".....#....",
    ".....#....",
    ".....#....",
    "..........",
]


def centre(grid, row: int, col: int) -> list[float]:
    """World (x, y) of a cell's centre."""
    return grid.cell_to_world(np.array([[row, col]]))[0].tolist()


def index(grid, row: int, col: int) -> int:
    return int(grid.free_index[row, col])


def observations(grid, rng: np.random.Generator, yaw: bool = True) -> Observations:
    """Three images and two utterances left of the wall, one image right of it."""
    spots = [(0, 1), (2, 3), (4, 4), (1, 8)]
    images = rng.gamma(1.0, 2.0, (4, 3))  # [T, K]
    return Observations(
        image_features=images,
        image_xy=[centre(grid, *s) for s in spots],
        image_trial=[0, 0, 0, 0],
        utterances=(("kitchen",), ("sofa", "kitchen")),
        word_xy=[centre(grid, 0, 1), centre(grid, 3, 2)],
        word_trial=[0, 0],
        image_yaw=[0.0, math.pi / 2, math.pi, 0.0] if yaw else None,
        modalities=(
            ModalityObservations(
                "objects", ("cup", "bed"), [centre(grid, 2, 7)], [0], [[2.0, 1.0]]
            ),
        ),
    )


@pytest.fixture
def problem(rng):
    grid = tiny_grid(ROWS)
    return grid, observations(grid, rng)


# -- the weights -----------------------------------------------------------------------------------


@pytest.mark.parametrize("kernel", ["uniform", "gaussian"])
@pytest.mark.parametrize("radius", [0.0, 0.05, 0.25, 1.0])
def test_weights_sum_to_one_observation_and_stay_on_free_cells(problem, kernel, radius):
    grid, obs = problem
    cells, _, _ = place_observations(grid, obs.image_xy, 0.0)
    cells = np.append(cells, -1)  # an unplaced observation: an empty row
    weights = footprint_weights(grid, cells, radius, kernel)  # [T + 1, N]
    assert weights.shape == (len(cells), grid.num_free)
    sums = np.asarray(weights.sum(axis=1)).ravel()
    np.testing.assert_allclose(sums[:-1], 1.0, rtol=0, atol=1e-12)
    assert sums[-1] == 0 and weights[len(cells) - 1].nnz == 0
    assert (weights.data > 0).all()
    dense = weights.toarray()
    assert (dense[np.arange(len(cells) - 1), cells[:-1]] > 0).all()  # its own cell always
    if radius < grid.resolution:  # only its own cell
        assert (weights.getnnz(axis=1)[:-1] == 1).all()


@pytest.mark.parametrize(("kernel", "fov"), [("uniform", None), ("gaussian", 90.0)])
def test_radius_zero_weights_are_the_own_cells_without_dijkstra(problem, kernel, fov, monkeypatch):
    """Radius 0 (``--word-footprint 0`` beside the images' footprint) gives each observation its
    own cell, weight 1: the arrays a radius below one cell gives through Dijkstra, bit for bit,
    without building the graph or calling Dijkstra (it ran both for nothing before)."""
    import scipy.sparse.csgraph

    import spcopyro.data.footprint as footprint_module

    grid, obs = problem
    cells, _, _ = place_observations(grid, obs.image_xy, 0.0)
    cells = np.concatenate([cells, [-1], cells[:2]])  # an unplaced one, two sharing a cell
    yaw = np.linspace(-3.0, 3.0, cells.size)
    dijkstra = footprint_weights(grid, cells, 0.01, kernel, yaw=yaw, fov=fov)  # own cell only
    done: list[int] = []

    def refused(*args, **kwargs):
        raise AssertionError("radius 0 built the graph or called Dijkstra")

    monkeypatch.setattr(scipy.sparse.csgraph, "dijkstra", refused)
    monkeypatch.setattr(footprint_module, "free_cell_graph", refused)
    zero = footprint_weights(grid, cells, 0.0, kernel, yaw=yaw, fov=fov, advance=done.append)
    assert zero.shape == dijkstra.shape and zero.dtype == dijkstra.dtype
    for name in ("data", "indices", "indptr"):
        a, b = getattr(zero, name), getattr(dijkstra, name)
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), name
    assert done == [np.unique(cells[cells >= 0]).size]  # every distinct observed cell


def test_uniform_weights_are_equal_and_gaussian_ones_fall_with_distance(problem):
    grid, _ = problem
    source = np.array([index(grid, 2, 2)])
    uniform = footprint_weights(grid, source, 0.2, "uniform").toarray()[0]
    reached = uniform > 0
    np.testing.assert_allclose(uniform[reached], 1 / reached.sum())
    gaussian = footprint_weights(grid, source, 0.2, "gaussian").toarray()[0]
    assert ((gaussian > 0) == reached).all()
    near, far = index(grid, 2, 3), index(grid, 2, 4)  # 0.1 m and 0.2 m away
    assert gaussian[source[0]] > gaussian[near] > gaussian[far] > 0
    sigma = 0.1
    np.testing.assert_allclose(gaussian[far] / gaussian[source[0]], math.exp(-2.0))  # d = 2 sigma
    np.testing.assert_allclose(gaussian[near] / gaussian[far], math.exp(1.5 * (0.1 / sigma) ** 2))


def test_footprint_never_crosses_a_wall(problem):
    """Left of the wall at (1, 4), a radius of 0.35 m reaches (1, 6) in a straight line
    (0.2 m) but not geodesically: the way round through the doorway is longer."""
    grid, _ = problem
    source = np.array([index(grid, 1, 4)])
    weights = footprint_weights(grid, source, 0.35).toarray()[0].reshape(-1)
    image = np.zeros(grid.shape)
    image[grid.free] = weights
    assert image[:4, 6:].sum() == 0  # nothing behind the wall
    assert image[1, 3] > 0 and image[4, 4] > 0  # within reach on its own side
    # through the doorway, the far side is reached when the radius allows the way round
    wide = footprint_weights(grid, source, 0.6).toarray()[0]
    image[grid.free] = wide
    assert image[4, 6] > 0 and image[1, 6] == 0  # (4, 6): 0.3 + 0.1 sqrt2 + 0.1 m round


def test_footprint_does_not_squeeze_through_a_diagonal_wall():
    """A wall one cell thick along a diagonal leaves diagonal steps between free cells: they
    must not carry the footprint across (no corner cutting)."""
    grid = tiny_grid(["...#", "..#.", ".#..", "#..."])
    source = np.array([index(grid, 0, 0)])
    weights = footprint_weights(grid, source, 10.0).toarray()[0]
    image = np.zeros(grid.shape)
    image[grid.free] = weights
    assert image[1, 3] == 0 and image[3, 3] == 0 and image[2, 2] == 0
    assert image[2, 0] > 0
    graph = free_cell_graph(grid)
    assert graph[index(grid, 0, 2), index(grid, 1, 3)] == 0  # the corner is not an edge


@pytest.mark.parametrize(
    "kernel, fov", [("uniform", None), ("gaussian", None), ("gaussian", 120.0)]
)
def test_footprints_of_a_long_map_run_dijkstra_on_windows_and_equal_the_whole_maps(
    monkeypatch, kernel, fov
):
    """Each chunk of sources runs Dijkstra on the free cells of a window around it, not on the
    whole map: one call over all N cells per 64 sources scanned [64, N] rows, and a 10^6-cell
    map's footprints took minutes of a fit (with no progress shown). The weights are bit for bit
    those of Dijkstra on the whole graph, observation by observation, walls and doorways
    included, several observations sharing a cell too."""
    from scipy.sparse import csgraph

    rows = ["." * 120, ("." * 39 + "#") * 3, ".." + "#" * 116 + "..", "." * 120]
    rows = ["".join(column) for column in zip(*(rows + rows[::-1]), strict=True)]
    grid = tiny_grid(rows)  # 120 x 8 cells: walls with openings at their ends, raster order
    rng = np.random.default_rng(3)
    cells = rng.choice(grid.num_free, 40)  # [T], repeated cells among them
    cells[5] = -1  # unplaced: an empty row
    yaw = rng.uniform(-np.pi, np.pi, cells.size)
    graph = free_cell_graph(grid)
    sizes = []
    dijkstra = csgraph.dijkstra

    def recorded(local, *args, **kwargs):
        sizes.append(local.shape[0])
        return dijkstra(local, *args, **kwargs)

    monkeypatch.setattr(csgraph, "dijkstra", recorded)
    fast = footprint_weights(grid, cells, 0.35, kernel, yaw=yaw if fov else None, fov=fov)
    assert sizes and max(sizes) < grid.num_free / 4, sizes  # windows: 0.35 m is 4 cells each side
    centres = grid.cell_to_world(grid.free_cells)
    for t, cell in enumerate(cells):  # the whole graph, one observation at a time
        row = fast[t].toarray()[0]
        if cell < 0:
            assert not row.any()
            continue
        d = dijkstra(graph, directed=False, indices=[cell], limit=0.35 * (1 + 1e-9) + 1e-12)[0]
        reach = np.isfinite(d)
        w = np.exp(-0.5 * (d / 0.175) ** 2) if kernel == "gaussian" else np.ones(d.size)
        if fov is not None:
            offset = centres - centres[cell]
            turn = np.angle(np.exp(1j * (np.arctan2(offset[:, 1], offset[:, 0]) - yaw[t])))
            reach &= (np.abs(turn) <= math.radians(fov) / 2 + 1e-12) | (np.arange(d.size) == cell)
        expected = np.zeros(d.size)
        expected[reach] = w[reach] / w[reach].sum()  # summed over the reached cells only
        np.testing.assert_array_equal(row, expected)


def test_field_of_view_keeps_the_cells_in_front(problem):
    grid, _ = problem
    source = np.array([index(grid, 2, 2)])
    east = footprint_weights(grid, source, 0.25, yaw=np.array([0.0]), fov=90.0).toarray()[0]
    image = np.zeros(grid.shape)
    image[grid.free] = east
    assert image[2, 2] > 0  # its own cell
    assert image[2, 4] > 0 and image[2, 3] > 0  # in front (east)
    assert image[2, 0] == 0 and image[0, 2] == 0 and image[4, 2] == 0  # behind, north, south
    np.testing.assert_allclose(east.sum(), 1.0)
    with pytest.raises(ValueError, match="yaw"):
        footprint_weights(grid, source, 0.25, fov=90.0)


def test_bad_footprint_settings_are_refused():
    for changes, name in [
        (dict(footprint_radius=-1.0), "footprint_radius"),
        (dict(footprint_radius=float("nan")), "footprint_radius"),
        (dict(footprint_kernel="box"), "footprint_kernel"),
        (dict(footprint_fov=0.0), "footprint_fov"),
        (dict(footprint_fov=400.0), "footprint_fov"),
    ]:
        with pytest.raises(ValueError, match=name):
            DataPreparation(**changes)
    settings = preset("paper-dp", footprint_radius=1.0, footprint_kernel="gaussian")
    assert settings.data.footprint_radius == 1.0 and settings.data.footprint_kernel == "gaussian"
    assert preset("paper-dp").data.footprint_radius == 0.0  # off by default: the paper


@pytest.mark.parametrize("bad", [True, -0.5, float("inf"), "0.5"])
def test_footprint_weights_refuse_a_bad_radius_as_the_preparation_does(bad):
    """footprint_weights' own radius check is config.is_number's, DataPreparation's: True (an
    int) passed it as a radius of 1 m."""
    with pytest.raises(ValueError, match=rf"footprint_radius={bad!r}: must be a finite number"):
        footprint_weights(tiny_grid(["..."]), np.array([0]), bad)


@pytest.mark.parametrize("bad", [True, 0.0, 400.0, float("nan"), "90"])
def test_footprint_weights_refuse_a_bad_fov_as_the_preparation_does(bad):
    """footprint_weights' own fov check is config.is_number's, DataPreparation's: True (an int)
    passed it as a field of view of 1 degree."""
    with pytest.raises(ValueError, match="footprint_fov"):
        DataPreparation(footprint_fov=bad)
    with pytest.raises(ValueError, match=rf"footprint_fov={bad!r}: must be None or degrees"):
        footprint_weights(tiny_grid(["..."]), np.array([0]), 0.5, yaw=np.zeros(1), fov=bad)


# -- the per-cell counts ---------------------------------------------------------------------------


def test_radius_zero_is_todays_counts_exactly(problem):
    grid, obs = problem
    plain = cell_counts(grid, obs, snap_distance=0.0)
    zero = cell_counts(grid, obs, snap_distance=0.0, footprint_radius=0.0)
    tiny = cell_counts(grid, obs, snap_distance=0.0, footprint_radius=0.01)  # own cell only
    for counts in (zero, tiny):
        np.testing.assert_array_equal(counts.cells, plain.cells)
        np.testing.assert_array_equal(counts.image_counts, plain.image_counts)
        np.testing.assert_array_equal(counts.word_counts, plain.word_counts)
        np.testing.assert_array_equal(counts.modalities[0].counts, plain.modalities[0].counts)


@pytest.mark.parametrize("fov", [None, 120.0])
def test_counts_are_the_weighted_sums_of_the_observations(problem, fov):
    grid, obs = problem
    radius = 0.3
    counts = cell_counts(
        grid, obs, snap_distance=0.0, footprint_radius=radius, footprint_kernel="gaussian",
        footprint_fov=fov,
    )  # fmt: skip
    image_cells, _, _ = place_observations(grid, obs.image_xy, 0.0)
    word_cells, _, _ = place_observations(grid, obs.word_xy, 0.0)
    image_w = footprint_weights(grid, image_cells, radius, "gaussian", yaw=obs.image_yaw, fov=fov)
    word_w = footprint_weights(grid, word_cells, radius, "gaussian").toarray()  # no fov for words
    expected_images = np.zeros((grid.num_free, 3))
    for t in range(obs.num_images):  # by hand: x~_c = sum_t w_tc x_t
        expected_images += image_w.toarray()[t][:, None] * obs.image_features[t][None, :]
    object_cells, _, _ = place_observations(grid, obs.modalities[0].positions, 0.0)
    object_w = footprint_weights(grid, object_cells, radius, "gaussian").toarray()
    reached = (image_w.toarray().sum(0) > 0) | (word_w.sum(0) > 0) | (object_w.sum(0) > 0)
    np.testing.assert_array_equal(counts.cells, np.flatnonzero(reached))
    np.testing.assert_allclose(counts.image_counts, expected_images[counts.cells], atol=1e-12)
    words = np.zeros((grid.num_free, len(counts.vocabulary)))
    words[:, counts.vocabulary.index("kitchen")] = word_w[0] + word_w[1]
    words[:, counts.vocabulary.index("sofa")] = word_w[1]
    np.testing.assert_allclose(counts.word_counts, words[counts.cells], atol=1e-12)
    # every modality's total is its observations' total: each weighs one observation
    plain = cell_counts(grid, obs, snap_distance=0.0)
    for spread, base in [
        (counts.image_counts, plain.image_counts),
        (counts.word_counts, plain.word_counts),
        (counts.modalities[0].counts, plain.modalities[0].counts),
    ]:
        np.testing.assert_allclose(spread.sum(0), base.sum(0), rtol=1e-12)
    # the further modality (an object count right of the wall) stays right of the wall
    columns = grid.free_cells[counts.cells][:, 1]  # [M]
    objects = counts.modalities[0].counts.sum(1)  # [M]
    assert objects[columns <= 5].sum() == 0 and objects[columns > 5].sum() == pytest.approx(3.0)


def test_warn_false_is_quiet_with_a_footprint_too(problem, caplog):
    """The footprint's counts recounted the plain ones with warnings on, so ``warn=False`` (a
    caller that counts the same observations twice) still warned of an observation off the map."""
    grid, obs = problem
    far = Observations(obs.image_features, obs.image_xy, obs.image_trial, obs.utterances,
                       [obs.word_xy[0], [55.0, 0.2]], obs.word_trial)  # fmt: skip
    for radius in (0.0, 0.2):
        caplog.clear()
        with caplog.at_level("WARNING", logger="spcopyro"):
            cell_counts(grid, far, footprint_radius=radius, warn=False)
        assert not caplog.records, radius
        with caplog.at_level("WARNING", logger="spcopyro"):
            cell_counts(grid, far, footprint_radius=radius)
        assert any("free space" in r.getMessage() for r in caplog.records), radius


def test_fov_without_yaw_is_a_clear_error(rng):
    grid = tiny_grid(ROWS)
    with pytest.raises(ValueError, match="yaw"):
        cell_counts(grid, observations(grid, rng, yaw=False), footprint_radius=0.2,
                    footprint_fov=90.0)  # fmt: skip


# -- the model on footprint counts ---------------------------------------------------------------


def footprint_data(problem, radius: float = 0.25):
    grid, obs = problem
    counts = cell_counts(grid, obs, snap_distance=0.0, footprint_radius=radius,
                         footprint_kernel="gaussian")  # fmt: skip
    return grid, obs, counts, make_model_data(grid, counts)


def objects_cfg(**changes):
    return config(concentrations={"objects": 0.7}, **changes)


def test_model_density_is_the_tempered_product_of_the_observations(problem):
    """log p*(state) of the Pyro model on the weighted counts minus the tempered product
    sum_t sum_c w_tc log Mult(x_t | phi_{C_c}) is the same number for any labels and
    parameters (it holds the multinomial coefficients only)."""
    grid, obs, counts, data = footprint_data(problem)
    cfg = objects_cfg(num_concepts=3)
    image_cells, _, _ = place_observations(grid, obs.image_xy, 0.0)
    word_cells, _, _ = place_observations(grid, obs.word_xy, 0.0)
    object_cells, _, _ = place_observations(grid, obs.modalities[0].positions, 0.0)
    words = np.zeros((obs.num_utterances, len(counts.vocabulary)))
    for u, tokens in enumerate(obs.utterances):
        for token in tokens:
            words[u, counts.vocabulary.index(token)] += 1
    per_modality = [
        (footprint_weights(grid, image_cells, 0.25, "gaussian").toarray(), obs.image_features),
        (footprint_weights(grid, word_cells, 0.25, "gaussian").toarray(), words),
        (footprint_weights(grid, object_cells, 0.25, "gaussian").toarray(),
         obs.modalities[0].counts),
    ]  # fmt: skip
    zero = data
    for modality in data.modalities:
        zero = zero.with_counts(modality.name, torch.zeros_like(modality.counts))
    differences = []
    for seed in range(4):
        state = init(data, cfg, torch.Generator().manual_seed(seed))
        tempered = 0.0
        for (weights, x), log_phi in zip(per_modality, state.log_emissions, strict=True):
            x = torch.as_tensor(x)  # [T, K]
            labels = state.labels  # [N]
            per_cell = multinomial_counts_log_prob(x[:, None, :], log_phi[labels][None])  # [T, N]
            tempered += float((torch.as_tensor(weights) * per_cell).sum())
        prior_only = model_log_density(state, zero, cfg)  # zero counts: no data term
        full = float(model_log_density(state, data, cfg))
        differences.append(full - float(prior_only) - tempered)
    np.testing.assert_allclose(differences, differences[0], rtol=0, atol=1e-8)


def test_gibbs_conditionals_equal_model_density_differences_with_footprint(problem):
    _, _, _, data = footprint_data(problem)
    cfg = objects_cfg(num_concepts=3, gamma=0.7)
    state = init(data, cfg, torch.Generator().manual_seed(1))
    rng = np.random.default_rng(0)
    cells = torch.as_tensor(np.sort(rng.choice(data.obs_cells.numpy(), 8, replace=False)))
    assert_conditionals_match_model(state, data, cfg, torch.cat([cells, torch.tensor([0])]))


@pytest.mark.parametrize("name", ["torch", "numba"])
def test_block_draws_follow_the_conditionals_with_footprint(name, rng):
    """500 wall-separated copies of the map, each with the same observations spread by the
    footprint (which must not reach into the next copy), share one state: one label sweep
    gives 500 independent draws of each first-block cell."""
    if name == "numba":
        pytest.importorskip("numba")
    copies, repeats = 500, 6
    one_grid = tiny_grid(ROWS)
    height = len(ROWS) + 1
    grid = tiny_grid(((ROWS + ["#" * len(ROWS[0])]) * copies)[:-1])
    base = observations(one_grid, rng)
    shift = np.array([0.0, grid.resolution * height])  # copy r sits r * height rows lower

    def moved(xy: np.ndarray, r: int) -> np.ndarray:
        top = (grid.height - one_grid.height) * grid.resolution  # copy 0 is at the top
        return np.asarray(xy) + np.array([0.0, top]) - r * shift

    obs = Observations(
        image_features=np.tile(base.image_features, (copies, 1)),
        image_xy=np.concatenate([moved(base.image_xy, r) for r in range(copies)]),
        image_trial=np.zeros(copies * base.num_images, dtype=np.int64),
        utterances=base.utterances * copies,
        word_xy=np.concatenate([moved(base.word_xy, r) for r in range(copies)]),
        word_trial=np.zeros(copies * base.num_utterances, dtype=np.int64),
    )
    counts = cell_counts(grid, obs, snap_distance=0.0, footprint_radius=0.3)
    n = one_grid.num_free
    per_copy = np.bincount(counts.cells // n, minlength=copies)
    assert (per_copy == per_copy[0]).all()  # every copy reached alike, none leaking
    plain_base = Observations(
        image_features=base.image_features, image_xy=base.image_xy, image_trial=base.image_trial,
        utterances=base.utterances, word_xy=base.word_xy, word_trial=base.word_trial,
    )  # fmt: skip
    one_counts = cell_counts(one_grid, plain_base, snap_distance=0.0, footprint_radius=0.3)
    np.testing.assert_allclose(counts.image_counts[: len(one_counts.cells)],
                               one_counts.image_counts, atol=1e-12)  # fmt: skip
    data = make_model_data(grid, counts)
    cfg = config(gamma=1.2)
    generator = torch.Generator().manual_seed(3)
    first_state = init(data, cfg, generator)
    # distinct image distributions per concept, so the spread counts move the conditionals
    distinct = torch.full((3, 3), 0.1, dtype=torch.float64).fill_diagonal_(0.8).log()
    state = first_state._replace(
        labels=first_state.labels[:n].repeat(copies),
        log_emissions=(distinct, first_state.log_emissions[1]),
    )
    plan = make_sweep_plan(data)
    first = plan.blocks[0].cells
    first = first[first < n]
    assert (data.observation_rows()[first] >= 0).sum() > 5
    sample_labels = backend_samplers(name).labels
    draws = torch.zeros(first.numel(), cfg.num_concepts)
    for _ in range(repeats):
        labels = sample_labels(state, data, cfg, generator, plan).view(copies, n)[:, first]
        draws += torch.nn.functional.one_hot(labels, cfg.num_concepts).sum(0)
    expected = label_log_conditionals(state, data, cfg, first).exp() * copies * repeats
    p_values = [stats.chisquare(draws[i].numpy(), expected[i].numpy()).pvalue
                for i in range(len(first))]  # fmt: skip
    assert min(p_values) * len(p_values) > 1e-3  # Bonferroni; a correct sampler fails < 1e-3


@pytest.mark.parametrize("name", ["torch", "numba"])
def test_dirichlet_posterior_counts_are_the_weighted_sums(problem, name):
    """The counts of concept l in the conditionals of theta_l, w_l (eqs. 16-17) are
    sum_t sum_{c: C_c = l} w_tc x_t."""
    grid, obs, counts, data = footprint_data(problem)
    cfg = objects_cfg(num_concepts=3)
    labels = torch.as_tensor(np.random.default_rng(2).integers(0, 3, grid.num_free))
    image_cells, _, _ = place_observations(grid, obs.image_xy, 0.0)
    weights = footprint_weights(grid, image_cells, 0.25, "gaussian").toarray()  # [T, N]
    expected = np.zeros((3, 3))
    for t in range(obs.num_images):
        for concept in range(3):
            expected[concept] += weights[t][labels.numpy() == concept].sum() * obs.image_features[t]
    if name == "torch":
        images = concept_statistics(labels, data, cfg).counts[0].numpy()
    else:
        pytest.importorskip("numba")
        from spcopyro.gibbs.numba_sweep import _statistics

        images = _statistics(labels.numpy(), data.obs_cells.numpy(), data, cfg)[1][0]
    np.testing.assert_allclose(images, expected, atol=1e-10)


@pytest.mark.parametrize("backend", ["torch", "numba"])
def test_cavi_elbo_never_decreases_with_footprint(problem, backend):
    if backend == "numba":
        pytest.importorskip("spcopyro.guides.numba_cavi")
    _, _, _, data = footprint_data(problem)
    cfg = objects_cfg(num_concepts=4, gamma=1.2)
    exact = dict(support=0, threshold=0.0, active_tolerance=0.0) if backend == "numba" else {}
    for seed in range(2):
        options = VariationalOptions(backend=backend, anneal_iterations=0, tolerance=0.0, **exact)
        q = initial_q(data, cfg, torch.Generator().manual_seed(seed), init="soft")
        run = run_variational(data, cfg, 12, options=options, q=q)
        steps = np.diff(run.objective)
        assert steps.min() > -1e-9 * np.abs(run.objective).max(), (seed, steps.min())


def test_spread_counts_matches_a_dense_product(problem):
    grid, obs = problem
    cells, _, _ = place_observations(grid, obs.image_xy, 0.0)
    weights = footprint_weights(grid, cells, 0.3)
    keep = np.array([0, 3, 9, 20])
    np.testing.assert_allclose(
        spread_counts(weights, obs.image_features, keep),
        weights.toarray()[:, keep].T @ obs.image_features,
    )


def test_fit_footprint_option_reaches_config_json(tmp_path):
    out = tmp_path / "fit"
    code = main(["fit", "--sweeps", "3", "--backend", "torch", "--footprint", "0.5",
                 "--footprint-kernel", "gaussian",
                 "--out", str(out)])  # fmt: skip
    assert code == 0
    settings = json.loads((out / "config.json").read_text())
    assert settings["data"]["footprint_radius"] == 0.5
    assert settings["data"]["footprint_kernel"] == "gaussian"
    assert settings["data"]["footprint_fov"] is None


@pytest.mark.slow
def test_footprint_benchmark_quick(tmp_path):
    """benchmarks/footprint.py --quick runs (its numbers are not asserted)."""
    out = tmp_path / "footprint.json"
    done = run_benchmark("footprint.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "ARI vs no obs" in done.stdout
    rows = json.loads(out.read_text())["rows"]
    assert {row["fit"] for row in rows} == {"no observations", "R = 0 m", "R = 0.5 m"}
