"""The teaching notebooks: every one runs from top to bottom (in its small mode, in a kernel that
imports this checkout's ``spcopyro``) without an error output, and the STORED notebooks -- what a
reader sees on GitHub without running anything -- carry their outputs (figures included), no error
and no progress bar, were run top to bottom, and stay small enough to review."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
EXPECTED = (
    "01_generative_model",
    "02_gibbs_sampling",
    "03_gibbs_vs_vi",
    "04_a_real_house",
    "05_your_own_variant",
)
"""Notebooks that must exist (issue 11)."""
SIZE_ENV = "SPCOPYRO_NOTEBOOK_SIZE"
"""The size switch every notebook reads: ``small`` here, full (the stored outputs) by default."""
MAX_BYTES = 1_500_000
"""A stored notebook, outputs included, stays below this size."""
SMALL_MODE_SECONDS = 120
"""What a notebook's small mode is meant to take (reported, not asserted: the machine's load
varies too much for a hard limit)."""


def _errors(notebook: nbformat.NotebookNode) -> list[dict]:
    return [
        output
        for cell in notebook.cells
        if cell.cell_type == "code"
        for output in cell.get("outputs", [])
        if output.get("output_type") == "error"
    ]


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_executes(path, tmp_path):
    notebook = nbformat.read(path, as_version=4)
    client = NotebookClient(notebook, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}})  # fmt: skip
    pythonpath = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    start = time.perf_counter()
    client.execute(env={**os.environ, "PYTHONPATH": pythonpath, SIZE_ENV: "small"})
    seconds = time.perf_counter() - start
    errors = _errors(notebook)
    assert not errors, errors
    if seconds > SMALL_MODE_SECONDS:
        print(f"{path.name}: small mode took {seconds:.0f} s (meant: < {SMALL_MODE_SECONDS} s)")


def test_there_are_notebooks():
    names = {p.stem for p in NOTEBOOKS}
    missing = [name for name in EXPECTED if name not in names]
    assert not missing, f"notebooks/ lacks {missing}"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_stored_notebook_is_small(path):
    size = path.stat().st_size
    assert size < MAX_BYTES, f"{path.name} is {size / 1e6:.2f} MB (limit {MAX_BYTES / 1e6} MB)"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_stored_notebook_has_outputs_and_no_error(path):
    notebook = nbformat.read(path, as_version=4)
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert code, f"{path.name} has no code cell"
    counts = [cell.get("execution_count") for cell in code]
    assert counts == list(range(1, len(code) + 1)), (
        f"{path.name} was not stored after one run from top to bottom: execution counts {counts}"
    )
    assert not _errors(notebook), f"{path.name} stores an error output"
    outputs = [output for cell in code for output in cell.get("outputs", [])]
    figures = [o for o in outputs if "image/png" in o.get("data", {})]
    assert figures, f"{path.name} stores no figure"
    assert sum(1 for cell in code if cell.get("outputs")) >= len(code) // 2, (
        f"{path.name}: most code cells store no output"
    )
    for output in outputs:
        text = output.get("text", "") if output.get("output_type") == "stream" else ""
        assert "it/s]" not in text and "\r" not in text, f"{path.name} stores a progress bar"
        assert "Warning" not in text or output.get("name") != "stderr", (
            f"{path.name} stores a warning: {text[:200]}"
        )
    for cell in code:
        assert "matplotlib.use(" not in cell.source, f"{path.name} forces a matplotlib backend"
        assert "progress=True" not in cell.source, f"{path.name} asks for progress bars"


_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?"
MAX_LISTED_NUMBERS = 12
"""A stored text output lists at most this many numbers in one bracketed group: more is a wall
of numbers a reader cannot take in (a plot, or the few that matter, says more)."""


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_stored_notebook_prints_no_wall_of_numbers(path):
    """Notebook 3 printed one cell's whole q(C_i) before and after its update, 30 masses each
    (0.033 thirty times, then 0.023 twenty-nine times around a 0.33); it now names the masses
    that stand out and the range of the rest."""
    notebook = nbformat.read(path, as_version=4)
    for k, cell in enumerate(c for c in notebook.cells if c.cell_type == "code"):
        for output in cell.get("outputs", []):
            if output.get("output_type") == "stream":
                text = output.get("text", "")
            else:
                text = output.get("data", {}).get("text/plain", "")
            for group in re.findall(r"[\[{(][^\[\]{}()]*[\]})]", text):
                count = len(re.findall(_NUMBER, group))
                assert count <= MAX_LISTED_NUMBERS, (
                    f"{path.name}, code cell {k + 1}, prints {count} numbers at once: {group[:200]}"
                )


_MAKES_FIGURE = re.compile(r"plt\.(?:subplots|figure|subplot_mosaic)\(")
_SETS_TITLE = re.compile(r"\.set_title\(|\.suptitle\(|plt\.title\(|\btitle=|\bshow_labels\(")
"""A title: matplotlib's, or the notebooks' ``show_labels(ax, labels, title)`` helper's."""


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_stored_notebook_titles_every_figure(path):
    """Every figure a notebook draws (each part of a code cell up to a ``plt.show()`` that makes
    one) sets a title saying what it shows. Notebook 3's ELBO-per-iteration figure (code cell
    4) and its marginal-error study (code cell 6), and notebook 5's ARI bar chart (code cell 7),
    had none. Read from the source: a title is there whichever mode runs it."""
    notebook = nbformat.read(path, as_version=4)
    untitled = [
        f"code cell {k + 1}, figure {j + 1}"
        for k, cell in enumerate(c for c in notebook.cells if c.cell_type == "code")
        for j, part in enumerate(re.split(r"plt\.show\(\)", cell.source))
        if _MAKES_FIGURE.search(part) and not _SETS_TITLE.search(part)
    ]
    assert not untitled, f"{path.name} draws figures without a title: {untitled}"


def test_plotting_leaves_the_matplotlib_backend_alone():
    """Library figures render inline in a notebook: importing spcopyro.figures.plotting must not
    choose a backend (it builds Figure objects, never pyplot)."""
    script = (
        "import matplotlib\n"
        "before = matplotlib.rcParams._get_backend_or_none()\n"
        "import spcopyro.figures.plotting, spcopyro.experiments.figures\n"
        "after = matplotlib.rcParams._get_backend_or_none()\n"
        "import sys\n"
        "assert before == after, (before, after)\n"
        "assert 'matplotlib.pyplot' not in sys.modules, 'pyplot imported'\n"
    )
    env = {key: value for key, value in os.environ.items() if key != "MPLBACKEND"}
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    completed = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                               text=True, timeout=120)  # fmt: skip
    assert completed.returncode == 0, completed.stderr[-2000:]


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_real_house_notebook_refuses_a_house_the_dataset_lacks(tmp_path):
    """A reader who sets notebook 4's HOUSE to a house the dataset does not hold (a typo) gets an
    error naming it and the houses there. The notebook used to fall back to the synthetic house,
    print that the dataset was not found, and then score that house against a region truth built
    as for a public house, since the dataset had been found."""
    from nbclient.exceptions import CellExecutionError

    from spcopyro.data import find_dataset_root

    try:
        root = find_dataset_root()
    except FileNotFoundError:  # $SPCOPYRO_DATA set to no dataset
        root = None
    if root is None or not (root / "room1dk5").is_dir():
        pytest.skip("the public dataset (room1dk5) is not here")
    notebook = nbformat.read(ROOT / "notebooks" / "04_a_real_house.ipynb", as_version=4)
    setup = [cell for cell in notebook.cells if 'HOUSE = "room1dk5"' in cell.source]
    assert len(setup) == 1, "notebook 4 no longer sets HOUSE = 'room1dk5' in one cell"
    setup[0].source = setup[0].source.replace('HOUSE = "room1dk5"', 'HOUSE = "room1dk"')
    first = notebook.cells.index(setup[0])
    client = NotebookClient(notebook, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}})  # fmt: skip
    pythonpath = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    env = {**os.environ, "PYTHONPATH": pythonpath, SIZE_ENV: "small", "SPCOPYRO_DATA": str(root)}
    with client.setup_kernel(env=env):
        for index, cell in enumerate(notebook.cells[:first]):
            client.execute_cell(cell, index)
        with pytest.raises(CellExecutionError) as error:
            client.execute_cell(setup[0], first)
    message = str(error.value)
    assert "FileNotFoundError" in message and "'room1dk'" in message, message[-2000:]
    assert "room1dk5" in message, message[-2000:]  # the houses it holds
    printed = "".join(o.get("text", "") for o in setup[0].outputs if o.output_type == "stream")
    assert "NOT FOUND" not in printed, printed


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_gibbs_vs_vi_race_runs_with_fewer_sweeps(tmp_path):
    """A reader who shortens notebook 3's race (SWEEPS = 50) still gets its curves: every method
    keeps a label map at least every iteration it is asked to thin by. The thinning was
    SWEEPS // 100, so below 100 sweeps Gibbs kept no map and the cell failed with "'NoneType'
    object is not iterable". Runs the setup cell and the race only."""
    notebook = nbformat.read(ROOT / "notebooks" / "03_gibbs_vs_vi.ipynb", as_version=4)
    sizes = [cell for cell in notebook.cells if "SWEEPS = 300 if SMALL else 2000" in cell.source]
    race = [cell for cell in notebook.cells if "curves, finals = {}, {}" in cell.source]
    assert len(sizes) == 1 and len(race) == 1, "notebook 3's setup or race cell moved"
    sizes[0].source = sizes[0].source.replace("SWEEPS = 300 if SMALL else 2000", "SWEEPS = 50")
    client = NotebookClient(notebook, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}})  # fmt: skip
    pythonpath = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    with client.setup_kernel(env={**os.environ, "PYTHONPATH": pythonpath, SIZE_ENV: "small"}):
        for cell in (sizes[0], race[0]):
            client.execute_cell(cell, notebook.cells.index(cell))  # raises on an error
    printed = "".join(o.get("text", "") for o in race[0].outputs if o.output_type == "stream")
    assert "final ARI" in printed and "gibbs + SW" in printed, printed


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_generative_model_tilt_plot_follows_the_sampled_gamma(tmp_path):
    """A reader who changes the coupling of notebook 1's 6-cell map (tiny_config's gamma = 1.0 to
    1.5) sees the Gibbs histogram labelled with that gamma and its tilted curve drawn beside it.
    The label said 'gamma = 1' whatever was sampled, and only the curves of 0.5, 1 and 2 were
    drawn. Runs the setup cells and the tilt plot only."""
    notebook = nbformat.read(ROOT / "notebooks" / "01_generative_model.ipynb", as_version=4)
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    tilt = [cell for cell in code if "def log_Z(" in cell.source]
    assert len(tilt) == 1, "notebook 1's tilt cell moved"
    old = 'prior="dirichlet", alpha=1.0, gamma=1.0,'
    assert old in tilt[0].source, "notebook 1's tiny_config changed"
    tilt[0].source = tilt[0].source.replace(old, old.replace("gamma=1.0", "gamma=1.5"))
    setup = code[: code.index(tilt[0])]
    probe = nbformat.v4.new_code_cell("print([t.get_text() for t in ax.get_legend().get_texts()])")
    client = NotebookClient(notebook, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}})  # fmt: skip
    pythonpath = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    with client.setup_kernel(env={**os.environ, "PYTHONPATH": pythonpath, SIZE_ENV: "small"}):
        for cell in [*setup, tilt[0], probe]:
            client.execute_cell(cell, 0)  # raises on an error
    legend = "".join(o.get("text", "") for o in probe.outputs if o.output_type == "stream")
    assert "Gibbs draws of pi_2 (gamma = 1.5," in legend, legend
    assert "Dir(pi) Z(pi, gamma = 1.5)" in legend, legend


@pytest.mark.parametrize("name", ["02_gibbs_sampling", "03_gibbs_vs_vi"])
def test_timed_notebooks_run_inference_on_one_torch_thread(name):
    """Notebooks 2 and 3 time the sampler and the registry's methods called directly (run_gibbs,
    get_method(...).run), which keep torch's default of a thread per core, where fit_house runs
    a map of this size on one (spcopyro._util.threads). Beside another job on a 2-core machine
    notebook 3's Gibbs took 28 s for its 2000 sweeps instead of 1.8 s and notebook 2's
    Swendsen-Wang chain 8.7 s instead of 1.3, so the stored times said little about the methods.
    Their setup cell sets one thread before any inference runs."""
    notebook = nbformat.read(ROOT / "notebooks" / f"{name}.ipynb", as_version=4)
    code = [cell.source for cell in notebook.cells if cell.cell_type == "code"]
    runs = [k for k, source in enumerate(code) if "run_gibbs(" in source or "get_method(" in source]
    sets = [k for k, source in enumerate(code) if "torch.set_num_threads(1)" in source]
    assert runs, f"{name} no longer runs inference outside fit_house"
    assert sets and sets[0] < runs[0], f"{name} runs inference before torch.set_num_threads(1)"


def _run_cells_and_probe(name, pick, probe_source, tmp_path, env=None):
    """Run notebook ``name``'s code cells for which ``pick(source)`` holds, in small mode, then
    ``probe_source``; the probe's printed text."""
    notebook = nbformat.read(ROOT / "notebooks" / f"{name}.ipynb", as_version=4)
    cells = [cell for cell in notebook.cells if cell.cell_type == "code" and pick(cell.source)]
    probe = nbformat.v4.new_code_cell(probe_source)
    client = NotebookClient(notebook, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}})  # fmt: skip
    pythonpath = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    full_env = {**os.environ, "PYTHONPATH": pythonpath, SIZE_ENV: "small", **(env or {})}
    with client.setup_kernel(env=full_env):
        for cell in [*cells, probe]:
            client.execute_cell(cell, 0)  # raises on an error
    return "".join(o.get("text", "") for o in probe.outputs if o.output_type == "stream")


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_real_house_notebook_names_the_colours_of_its_three_maps(tmp_path):
    """Notebook 4's region truth, fit and nearest-utterance panels (each in its own colours, not
    matched between panels) had no legend: a reader could not tell which colour was which place.
    Each panel now has one, largest label first: the truth's place names, each fit concept's best
    word and id, (E)'s words. Runs the cells up to that figure (not the paper-dp contrast)."""
    import json

    notebook = nbformat.read(ROOT / "notebooks" / "04_a_real_house.ipynb", as_version=4)
    code = [cell.source for cell in notebook.cells if cell.cell_type == "code"]
    figure = [k for k, source in enumerate(code) if "truth_labels = " in source]
    assert len(figure) == 1, "notebook 4's truth figure cell moved"
    wanted = set(code[: figure[0] + 1])
    probe = (
        "import json\n"
        "def _expected(image, name):\n"
        "    image = np.where(house.grid.free, image, -1)\n"
        "    labels, sizes = np.unique(image[image >= 0], return_counts=True)\n"
        "    return [name(int(k)) for k in labels[np.argsort(-sizes)]]\n"
        "def _best(c):\n"
        "    return 'no word heard' if result.heard(c) == 0 else result.top_words(c, 1)[0][0]\n"
        "print(json.dumps({\n"
        "    'legends': [[t.get_text() for t in ax.get_legend().get_texts()] for ax in axes],\n"
        "    'truth': _expected(truth_labels, lambda k: truth_names[k]),\n"
        "    'fit': _expected(mapped, lambda c: f'{_best(c)} ({c})'),\n"
        "    'nearest': _expected(nearest, lambda v: obs.vocabulary[v]),\n"
        "    'places': truth_names, 'vocabulary': list(obs.vocabulary),\n"
        "}))\n"
    )
    printed = _run_cells_and_probe(
        "04_a_real_house",
        lambda source: source in wanted and 'preset("paper-dp")' not in source,
        probe,
        tmp_path,
    )
    seen = json.loads(printed.strip().splitlines()[-1])
    truth, fit, nearest = seen["legends"]
    assert truth == seen["truth"] and set(truth) <= set(seen["places"]), seen
    assert fit == seen["fit"] and len(fit) >= 2, seen
    assert nearest == seen["nearest"] and set(nearest) <= set(seen["vocabulary"]), seen


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_gibbs_notebook_titles_its_log_joint_figures(tmp_path):
    """Notebook 2's figure of one chain's log joint and concepts in use, and the figure of the
    convergence check's chains, had no title. Runs the setup, the chain and the check only."""
    picked = ("import os\n", "looks = sorted(", "result, diagnostics = fit_house_converged(")
    printed = _run_cells_and_probe(
        "02_gibbs_sampling",
        lambda source: source.startswith(picked),
        "print(repr(top.get_title()), repr(ax.get_title()))",
        tmp_path,
    )
    assert "'one chain, 150 sweeps: log joint and concepts in use'" in printed, printed
    assert "'2 chains: log joint'" in printed, printed


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_variant_notebook_bar_chart_names_its_missing_and_flat_bars(tmp_path):
    """Notebook 5's ARI bar chart left the stick-breaking variant an empty slot: no Gibbs bar
    (Gibbs has no stick-breaking option) and a CAVI bar of ARI 0.00, too low to see. A bar that
    is missing or below 0.05 is now named on the chart. Runs the whole notebook in small mode."""
    printed = _run_cells_and_probe(
        "05_your_own_variant",
        lambda source: True,
        "print([t.get_text() for t in ax.texts])",
        tmp_path,
    )
    import ast

    texts = ast.literal_eval(printed.strip().splitlines()[-1])  # the chart's texts
    assert "no gibbs" in texts, texts
    assert any(text.startswith("0.0") for text in texts), texts
