"""Warnings and errors that tell the user to change a setting name it as Python does, then the
command line's flag in parentheses (:func:`spcopyro._util.messages.setting`): they reach a
library caller (``fit_house``, ``SpCoGibbs`` under ``pyro.infer.MCMC``, guides under ``SVI``) as
they reach ``spcopyro fit``, and named the flags alone ("lower --gamma")."""

from __future__ import annotations

import pytest

from spcopyro._util.messages import setting
from spcopyro.config import SpCoConfig, preset
from spcopyro.fit.house import prepare_model_data
from spcopyro.guides.factors import stick_breaking_warning
from spcopyro.synthetic import make_house


@pytest.fixture(scope="module")
def house():
    return make_house(seed=0)


def logged(caplog, call, *args, **kwargs) -> list[str]:
    caplog.clear()
    with caplog.at_level("WARNING", logger="spcopyro"):
        call(*args, **kwargs)
    return [r.getMessage() for r in caplog.records]


def test_setting_names_python_then_the_flag():
    assert setting("gamma", "--gamma") == "gamma (fit's --gamma)"
    assert setting("prior='area'", "--prior area", "where") == "prior='area' (where's --prior area)"


def test_model_setting_warnings_of_a_library_fit_name_the_python_settings(caplog, house):
    """prepare_model_data (fit_house's first step) said "raise gamma or lower num_concepts
    (fit's --gamma, --concepts)" and "lower --gamma": the flags alone where gamma freezes."""
    low = logged(caplog, prepare_model_data, house, preset("original-code", gamma=1.0))
    (below,) = [m for m in low if "critical coupling" in m]
    assert "raise gamma (fit's --gamma) or lower num_concepts (fit's --concepts)" in below
    high = logged(caplog, prepare_model_data, house, preset("original-code", gamma=12.0))
    (freezing,) = [m for m in high if "freezes" in m]
    assert "lower gamma (fit's --gamma): regions form just above the critical 2.48" in freezing
    assert "--gamma" not in freezing.replace("(fit's --gamma)", "")
    sticks = stick_breaking_warning(SpCoConfig(alpha=1e7, num_concepts=20))
    assert "give the stick-breaking one an alpha (fit's --alpha) of order 1-10" in sticks


def test_a_library_fits_flat_q_warning_names_the_options_and_init(caplog):
    """fit_house(method="cavi") with VariationalOptions(anneal_iterations=20) was told "Try
    anneal_iterations=0 (--method-option; ...); or a fitted start (fit --init-from OUT, ...)",
    and SVI "use --method cavi": a library caller passes options=, init= and method=."""
    from spcopyro.fit.house import fit_house
    from spcopyro.guides.options import VariationalOptions
    from spcopyro.guides.svi_method import SVIOptions, flat_q_advice
    from spcopyro.synthetic import HouseSpec

    small = make_house(seed=0, spec=HouseSpec.scaled(30, 40, num_rooms=2))
    options = VariationalOptions(anneal_iterations=20)
    fit = fit_house
    said = logged(caplog, fit, small, preset("paper-dp"), method="cavi", sweeps=40,
                  options=options, progress=False)  # fmt: skip
    (flat,) = [m for m in said if "ended near uniform" in m]
    assert (
        "Try anneal_iterations=0 (fit's --method-option anneal_iterations=0): it annealed" in flat
    )
    assert flat.endswith("a fitted start, e.g. of a Gibbs fit: init=result (fit's --init-from OUT)")
    way_out = flat_q_advice(SVIOptions(), resumed=False)[1]
    assert way_out.startswith("Start from a fitted map, init=result (fit's --init-from OUT) or ")
    assert way_out.endswith("or use method='cavi' (fit's --method cavi)")
