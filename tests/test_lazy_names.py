"""Names imported on first use (PEP 562), one pattern: a package's table of each name's module and
:func:`spcopyro._util.lazy.lazy_names` (spcopyro.gibbs's kernel names, spcopyro.guides's Pyro
guide, the rosbag package's and the features package's names); the method registry's table of
classes made with :func:`spcopyro._util.lazy.load`."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "spcopyro"

LAZY = {
    "spcopyro.gibbs": ("SpCoGibbs", "spcopyro.gibbs.kernel"),
    "spcopyro.guides": ("WrongLossError", "spcopyro.guides.mean_field"),
    "spcopyro.robot.rosbag": ("BagImportReport", "spcopyro.robot.rosbag.report"),
    "spcopyro.features": ("WeightsNotFoundError", "spcopyro.features.backbone"),
}
"""A package with names imported on first use: one such name and its module."""


@pytest.mark.parametrize("package", sorted(LAZY))
def test_a_lazy_name_is_listed_imported_from_its_module_and_kept(package):
    module = importlib.import_module(package)
    name, home = LAZY[package]
    assert name in dir(module) and name in module.__all__
    value = getattr(module, name)
    assert value is getattr(importlib.import_module(home), name)
    assert vars(module)[name] is value  # kept: the next lookup is a plain one
    with pytest.raises(AttributeError, match=rf"module '{package}' has no attribute 'no_such'"):
        module.no_such  # noqa: B018


def test_every_lazy_name_is_in_dir_and_all():
    """What each package imports on first use is what it exports, and dir() lists it."""
    for package in LAZY:
        module = importlib.import_module(package)
        lazy = set(dir(module)) - set(vars(module))
        assert lazy <= set(module.__all__), package


def _module_getattrs() -> list[str]:
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        found += [
            str(path.relative_to(PACKAGE.parent))
            for node in tree.body
            if isinstance(node, ast.FunctionDef) and node.name in ("__getattr__", "__dir__")
        ]
    return found


def test_no_module_writes_its_own_getattr():
    """A package's lazy names are a table and ``lazy_names``: spcopyro.gibbs and spcopyro.guides
    wrote their ``__getattr__`` by hand (without ``__dir__``, nor keeping what they imported),
    the rosbag and features packages theirs, each a little different."""
    assert _module_getattrs() == []


def test_the_registry_makes_each_method_of_its_table_once():
    from spcopyro.fit import registry
    from spcopyro.inference.names import INFERENCE_METHOD_NAMES

    assert tuple(registry._CLASSES) == INFERENCE_METHOD_NAMES
    for name, (module, cls) in registry._CLASSES.items():
        method = registry.INFERENCE_METHODS[name]
        assert type(method) is getattr(importlib.import_module(module), cls)
        assert registry.get_method(name) is method
