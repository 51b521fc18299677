"""Questions without torch (issue 25 item 2): ``spcopyro --help``, ``fit --help``, ``where``,
``show`` and ``export`` on a saved fit import none of torch, pyro and numba.

Each command runs in a fresh interpreter, which then prints the heavy modules it imported.
Nothing here times anything: ``python benchmarks/fixed_cost.py --startup-only`` measures the
start-up of these commands as whole processes.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from spcopyro.cli.main import build_parser, main
from spcopyro.synthetic import HouseSpec, write_synthetic

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("torch", "pyro", "numba")
# What a command reading or drawing files needs, not the parser: --help imports none of them.
FILE_LIBRARIES = ("cv2", "yaml", "scipy", "matplotlib", "PIL", "rosbags")
# Modules of spcopyro itself that --help has no use for (issue 25): the point estimate (numpy's
# search, ~7 ms; the parser reads its names from estimate_names) and the bag importer with what
# it pulls (~12 ms; the rosbag package's __init__ imports its names on first use).
OWN_LEFTOVERS = ("spcopyro.results.point_estimate", "spcopyro.robot.rosbag.importer")
# What writing outputs pulls in (spcopyro._util.outputs: zipfile for .npz, secrets for the names
# of folders set aside; ~8 ms with the module): commands import it when they write, not --help.
WRITING_LIBRARIES = ("zipfile", "secrets")
WATCHED = HEAVY + FILE_LIBRARIES + OWN_LEFTOVERS + WRITING_LIBRARIES
MARK = "heavy modules imported:"

# The command, then the heavy modules it prints as imported, on its last line of stdout.
_PROGRAM = f"""
import json, sys
sys.argv = ["spcopyro", *json.loads(sys.argv[1])]
try:
    from spcopyro.cli.main import console_main
    console_main()
finally:
    print({MARK!r}, json.dumps(sorted(m for m in {WATCHED!r} if m in sys.modules)),
          flush=True)
"""


def _env() -> dict[str, str]:
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    return {**os.environ, "PYTHONPATH": path, "CI": "1"}


def heavy_imports(args: list[str], heavy: tuple[str, ...] = HEAVY) -> tuple[list[str], str]:
    """Run ``spcopyro ARGS`` in a fresh interpreter: the modules of ``heavy`` it imported, its
    stdout."""
    done = subprocess.run(
        [sys.executable, "-c", _PROGRAM, json.dumps(args)],
        capture_output=True, text=True, env=_env(), timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, f"spcopyro {' '.join(args)}: {done.stderr[-3000:]}"
    *printed, last = done.stdout.rstrip("\n").split("\n")
    assert last.startswith(MARK), done.stdout[-3000:]
    return [m for m in json.loads(last[len(MARK) :]) if m in heavy], "\n".join(printed)


@pytest.fixture(scope="module")
def saved_fit(tmp_path_factory) -> tuple[Path, Path]:
    """A house folder and a fit of it saved with the library (a few sweeps)."""
    from spcopyro.config import preset
    from spcopyro.data import load_house
    from spcopyro.fit.house import fit_house

    root = tmp_path_factory.mktemp("startup")
    house_dir = write_synthetic(root / "data", seed=1, spec=HouseSpec(height=40, width=50,
                                                                      num_rooms=3))  # fmt: skip
    settings = preset("original-code", gamma=3.0, num_concepts=6)
    result = fit_house(load_house(house_dir), settings, sweeps=5, progress=False)
    return house_dir, result.save(root / "fit")


def _word(fit: Path) -> str:
    concepts = json.loads((fit / "concepts.json").read_text())
    return next(c["top_words"][0][0] for c in concepts if c["top_words"])


def test_help_imports_no_torch():
    """Nor OpenCV, PyYAML, scipy, matplotlib, PIL or rosbags (0.02-0.05 s of start-up for cv2 and
    yaml, which map_server and the rosbag package imported with themselves)."""
    imported, printed = heavy_imports(["--help"], HEAVY + FILE_LIBRARIES)
    assert imported == []
    assert "fit" in printed and "where" in printed and "export" in printed


def test_help_imports_neither_point_estimate_nor_bag_importer():
    """The parser's choices of ``--point-estimate`` and the rosbag commands' options need neither
    :mod:`spcopyro.results.point_estimate` nor :mod:`spcopyro.robot.rosbag.importer`; nor does
    any command's parser need zipfile or secrets (:mod:`spcopyro._util.outputs`, which
    study.commands imported at the top for ``file_identity``)."""
    imported, printed = heavy_imports(["--help"], OWN_LEFTOVERS + WRITING_LIBRARIES)
    assert imported == []
    assert "import-bag" in printed


def test_the_command_lines_samplers_are_the_fits():
    """``fit``'s options spelt ("gibbs", "vi-gibbs") five times over; one public constant of the
    torch-free cli.fit_options now, the same as the fit's own. Spelt once, in the torch-free
    inference.names, which cli.fit_options, fit.house and figures.trace import (it was spelt in
    each of the three); the figures use it by its name (figures.trace's private alias _CHAINS
    is gone)."""
    from spcopyro.cli import fit_options
    from spcopyro.figures import plotting, trace
    from spcopyro.fit.house import SAMPLERS
    from spcopyro.inference import names

    assert names.SAMPLERS == ("gibbs", "vi-gibbs")
    for spelt in (fit_options.SAMPLERS, SAMPLERS, trace.SAMPLERS, plotting.SAMPLERS):
        assert spelt is names.SAMPLERS
    assert not hasattr(trace, "_CHAINS")


def test_point_estimate_names_are_the_light_modules():
    """``fit --point-estimate``'s choices are the point estimate's own (re-exported there)."""
    from spcopyro.results import estimate_names, point_estimate

    for name in estimate_names.__all__:
        assert getattr(point_estimate, name) is getattr(estimate_names, name)
    assert point_estimate.check_point_estimate("vi") == "vi"
    with pytest.raises(SystemExit):
        build_parser().parse_args(["fit", "--out", "x", "--point-estimate", "nope"])
    args = build_parser().parse_args(["fit", "--out", "x", "--point-estimate", "binder"])
    assert args.point_estimate == "binder"


_ROSBAG_NAMES = """
import importlib, sys
import spcopyro.robot.rosbag as package
assert "spcopyro.robot.rosbag.importer" not in sys.modules, "imported with the package"
assert sorted(package.__all__) == sorted(package._HOMES), package.__all__
for name in package.__all__:
    home = importlib.import_module("spcopyro.robot.rosbag." + package._HOMES[name])
    value = getattr(package, name)
    assert value is getattr(home, name), name
    assert getattr(value, "__module__", home.__name__) == home.__name__, name
    assert name in dir(package), name
namespace = {}
exec("from spcopyro.robot.rosbag import *", namespace)
assert {n for n in namespace if not n.startswith("__")} == set(package.__all__), namespace
try:
    package.not_a_name
except AttributeError as error:
    assert "not_a_name" in str(error), error
else:
    raise AssertionError("package.not_a_name did not raise AttributeError")
from spcopyro.robot.rosbag import importer
assert importer.import_bags is package.import_bags
print("ok")
"""


def test_rosbag_package_names_import_on_first_use():
    """``from spcopyro.robot.rosbag import X`` works for every public X (and ``*``), each X the
    object its module defines, though importing the package loads none of them."""
    done = subprocess.run([sys.executable, "-c", _ROSBAG_NAMES], capture_output=True, text=True,
                          env=_env(), timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip() == "ok"


def test_fit_help_imports_no_torch():
    """``fit --help`` lists the methods, starts and backends from :mod:`spcopyro.inference.names`
    (no torch), and those are the registry's, the starts' and the sweep's own."""
    from spcopyro.fit.registry import INFERENCE_METHODS
    from spcopyro.inference import names

    imported, printed = heavy_imports(["fit", "--help"], HEAVY + FILE_LIBRARIES)
    assert imported == []
    for name in (*names.INFERENCE_METHOD_NAMES, *names.INITS, *names.BACKENDS):
        assert name in printed
    assert tuple(INFERENCE_METHODS) == names.INFERENCE_METHOD_NAMES


@pytest.mark.parametrize(
    "command",
    [
        ["where", "{fit}", "{word}"],
        ["-v", "where", "{fit}", "{word}", "--prior", "pi"],
        ["where", "{fit}", "{word}", "--out", "{tmp}/where.png"],
        ["export", "{fit}", "--nav2", "{tmp}/keepout", "--word", "{word}"],
        ["export", "{fit}", "--nav2", "{tmp}/speed", "--word", "{word}", "--mode", "speed"],
        ["show", "{house}", "--out", "{tmp}/house.png"],
        ["show", "--out", "{tmp}/default.png"],
        ["where", "--help"],
    ],
    ids=[
        "where",
        "where-pi",
        "where-png",
        "export-keepout",
        "export-speed",
        "show-house",
        "show-default",
        "where-help",
    ],
)
def test_questions_on_a_saved_fit_import_no_torch(saved_fit, tmp_path, command):
    house, fit = saved_fit
    values = dict(fit=fit, word=_word(fit), tmp=tmp_path, house=house)
    args = [part.format(**values) for part in command]
    imported, printed = heavy_imports(args)
    assert imported == [], f"spcopyro {' '.join(args)} imported {imported}"
    assert printed.strip()
    if "--out" in args and "--help" not in args:
        assert Path(args[args.index("--out") + 1]).is_file()


def test_fit_help_still_lists_every_option(capsys):
    """``fit``'s parse and help are whole, and the parser holds every command."""
    with pytest.raises(SystemExit):
        main(["-v", "fit", "--help"])
    assert "--backend {auto,torch,numba}" in capsys.readouterr().out
    parser = build_parser()
    assert parser.parse_args(["fit", "--out", "x", "--backend", "numba"]).backend == "numba"
    (sub,) = (a for a in parser._actions if hasattr(a, "choices") and a.choices
              and "fit" in a.choices)  # fmt: skip
    assert "fit" in sub.choices and "where" in sub.choices
