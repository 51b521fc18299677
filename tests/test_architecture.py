"""The package's import graph: one direction, no cycle, and light imports where they matter.

Every ``import`` and ``from ... import`` of every module is read with :mod:`ast` -- module-level,
inside functions and under ``TYPE_CHECKING`` alike, since a cycle hidden by a lazy import is still
a cycle -- and checked against the layers below (the issue-9 architecture):
plumbing (``_util``) -> maps/data -> model -> inference (likelihood, gibbs, guides) -> results
-> metrics/baselines/figures -> fit -> robot -> experiments/study -> CLI. A module may import its
own layer and lower ones only. The layers are folders: every subpackage of ``spcopyro`` sits in
one layer, and the top level keeps only the model core (:data:`LOOSE_MODULES`).
"""

from __future__ import annotations

import ast
import functools
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "spcopyro"

LAYERS: tuple[tuple[str, ...], ...] = (
    ("_util",),
    ("config", "distributions", "maps"),
    ("data", "synthetic"),
    ("model", "model_checks"),
    ("likelihood", "inference"),
    ("gibbs", "guides", "simulate"),
    ("results",),
    ("metrics", "baselines", "features", "figures"),
    ("fit",),
    ("robot",),
    ("experiments",),
    ("study",),
    ("cli", "__main__"),
)
"""Layer of every top-level module or subpackage of spcopyro, lowest first."""


def _module_names() -> dict[str, Path]:
    modules = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join(parts)] = path
    return modules


MODULES = _module_names()


@functools.cache
def _tree(module: str) -> ast.Module:
    """``module``'s source parsed, once for every check that reads it."""
    return ast.parse(MODULES[module].read_text(encoding="utf-8"))


def _imports(module: str) -> set[str]:
    """The spcopyro modules that ``module`` imports anywhere in its source."""
    path = MODULES[module]
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(_tree(module)):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            names = [base] + [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        for name in names:
            while name and name not in MODULES:
                name = name.rsplit(".", 1)[0] if "." in name else ""
            if name.startswith("spcopyro.") and name != module:
                found.add(name)
    return found


GRAPH = {module: _imports(module) for module in MODULES}


def _layer(module: str) -> int:
    top = module.split(".")[1]
    for index, names in enumerate(LAYERS):
        if top in names:
            return index
    raise AssertionError(f"{module} is in no layer of LAYERS: add its top-level name")


INNER = [module for module in MODULES if module != "spcopyro"]
"""Every module but the package's own ``__init__`` (which only holds the version)."""


def test_every_module_has_a_layer():
    for module in INNER:
        _layer(module)


def test_imports_point_down_the_layers():
    wrong = [
        f"{module} (layer {_layer(module)}) imports {target} (layer {_layer(target)})"
        for module, targets in GRAPH.items()
        if module != "spcopyro"
        for target in targets
        if target != "spcopyro" and _layer(target) > _layer(module)
    ]
    assert not wrong, "\n".join(wrong)


def test_no_import_cycle():
    """Tarjan's strongly connected components of the module graph are all single modules."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in GRAPH[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for module in GRAPH:
        if module not in index:
            visit(module)
    assert not cycles, f"import cycles: {cycles}"


def test_the_checker_sees_a_cycle_and_a_wrong_direction(monkeypatch):
    """The two checks above can fail: a made-up edge model -> fit breaks both."""
    graph = {module: set(targets) for module, targets in GRAPH.items()}
    graph["spcopyro.model"].add("spcopyro.fit.house")
    monkeypatch.setattr(sys.modules[__name__], "GRAPH", graph)
    with pytest.raises(AssertionError, match="imports spcopyro.fit.house"):
        test_imports_point_down_the_layers()
    with pytest.raises(AssertionError, match="import cycles"):
        test_no_import_cycle()


def test_fit_house_imports_refine_at_its_top():
    """fit.house imported fit.refine inside prepare_model_data and fit_house while refine
    imported house back (f578eb4); fb0676b ended that and the cycle check above keeps it
    ended, so nothing holds the import inside a function."""
    tree = _tree("spcopyro.fit.house")
    top = {node.module for node in tree.body if isinstance(node, ast.ImportFrom)}
    inner = {
        node.module
        for function in ast.walk(tree)
        if isinstance(function, ast.FunctionDef)
        for node in ast.walk(function)
        if isinstance(node, ast.ImportFrom)
    }
    assert "spcopyro.fit.refine" in top and "spcopyro.fit.refine" not in inner, inner


def _private_imports(wanted: Callable[[str, str], bool]) -> list[str]:
    """Each ``from X import _name`` (a dunder is not private) of a module where
    ``wanted(module, X)``, as "module:line imports X._name"."""
    return [
        f"{module}:{node.lineno} imports {node.module}.{alias.name}"
        for module in MODULES
        for node in ast.walk(_tree(module))
        if isinstance(node, ast.ImportFrom) and node.module and wanted(module, node.module)
        for alias in node.names
        if alias.name.startswith("_") and not alias.name.startswith("__")
    ]


@pytest.mark.parametrize(
    "protected",
    [
        "spcopyro.figures.plotting", "spcopyro.cli.fit_write", "spcopyro._util.folder_commit",
        "spcopyro._util.outputs",
    ],
)  # fmt: skip
def test_no_module_imports_a_private_name_of(protected):
    """What another module calls of these is public, one of their own package too (another
    package's import of any private name is the test below's): the navigation figures and the
    study's label maps imported plotting's private aliases ``_save`` (of figures/png.py's
    ``save_figure``), ``_extent`` and ``_show_image`` (of map_axes'), which they now import,
    public, from where they are defined. The loose modules model and model_checks, listed here
    once (fit.house imported the model's _check_concentration_names and guides.mean_field its
    _calling_elbo), are another package's to every module that imports them: the test below
    covers them."""
    offenders = _private_imports(lambda module, source: source == protected)
    assert not offenders, "\n".join(offenders)


def _top(module: str) -> str:
    """``module``'s top-level package or loose module under spcopyro ("" for spcopyro's own)."""
    return f"{module}.".split(".")[1]


def test_no_package_imports_a_private_name_of_another():
    """A private name is its own package's (folder's, or loose module's): study.sources imported
    map_yaml's _read_map_yaml and map_server's _read_occupancy_yaml, experiments.open_plan
    floor_plan's _floor_plan and robot.map_simulation its _FloorPlan, all public now."""
    offenders = _private_imports(
        lambda module, source: source.startswith("spcopyro.") and _top(source) != _top(module)
    )
    assert not offenders, "\n".join(offenders)


def test_no_module_stands_in_for_a_class_with_any():
    """cli.fit_finished and cli.fit_write annotated ``job`` with ``Any as FitJob`` (the class
    lived in cli.fit, which imports both): a checker saw no FitJob. It lives in cli.fit_job now,
    which all three import."""
    offenders = [
        f"{module}:{node.lineno} imports typing.Any as {alias.asname}"
        for module in MODULES
        for node in ast.walk(_tree(module))
        if isinstance(node, ast.ImportFrom) and node.module == "typing"
        for alias in node.names
        if alias.name == "Any" and alias.asname not in (None, "Any")
    ]
    assert not offenders, "\n".join(offenders)


@pytest.mark.parametrize(
    "part", ["baselines", "metrics", "results.semantic_map", "inference.initialisation"]
)
def test_baselines_and_metrics_do_not_import_inference(part):
    forbidden = ("spcopyro.gibbs", "spcopyro.results.result", "spcopyro.fit")
    offenders = [
        f"{module} imports {target}"
        for module, targets in GRAPH.items()
        if module == f"spcopyro.{part}" or module.startswith(f"spcopyro.{part}.")
        for target in targets
        if target.startswith(forbidden)
    ]
    assert not offenders, "\n".join(offenders)


LOOSE_MODULES = (
    "__init__", "__main__", "distributions", "likelihood", "model", "model_checks", "simulate",
)  # fmt: skip
"""The only modules at the top of ``spcopyro/``: the model core. Everything else is in a folder."""

MAX_MODULE_LINES = 600
"""A module past this many lines usually holds two responsibilities."""


def test_the_top_level_holds_only_the_model_core():
    loose = sorted(path.stem for path in PACKAGE.glob("*.py"))
    assert loose == sorted(LOOSE_MODULES), f"loose modules at the top of spcopyro/: {loose}"
    assert len(loose) <= 8


def test_every_folder_is_one_layer():
    folders = sorted(path.parent.name for path in PACKAGE.glob("*/__init__.py"))
    layered = {name for names in LAYERS for name in names}
    assert not set(folders) - layered, f"folders in no layer: {set(folders) - layered}"


def test_no_module_is_over_600_lines():
    long = {
        str(path.relative_to(PACKAGE.parent)): lines
        for path in PACKAGE.rglob("*.py")
        if (lines := len(path.read_text().splitlines())) > MAX_MODULE_LINES
    }
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


def test_importing_the_model_loads_neither_opencv_nor_yaml():
    code = (
        "import sys, spcopyro.model, spcopyro.likelihood, spcopyro.gibbs; "
        "print(sorted(m for m in ('cv2', 'yaml', 'matplotlib', 'sklearn', 'torchvision') "
        "if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True,
        cwd=PACKAGE.parent,
    )  # fmt: skip
    assert out.stdout.strip() == "[]", out.stdout
