"""Seeded runs whose outputs are pinned by ``test_pinned_outputs.py``.

The digests in that test were recorded *before* the inference-interface refactor (issue 9), so
"behaviour unchanged" is checked, not assumed. Each scenario returns named arrays; the test hashes
labels exactly and floating-point tables at 12 significant digits (the last bits of a BLAS
product may depend on the thread count, which is not behaviour).
"""

from __future__ import annotations

import hashlib

import numpy as np
import torch


def digest(arrays: dict[str, np.ndarray]) -> str:
    """sha256 of the arrays: integers exactly, floats as 12-significant-digit text."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.asarray(arrays[name])
        h.update(name.encode())
        if np.issubdtype(a.dtype, np.floating):
            h.update(" ".join(f"{v:.12g}" for v in a.ravel()).encode())
        else:
            h.update(np.ascontiguousarray(a.astype(np.int64)).tobytes())
        h.update(repr(a.shape).encode())
    return h.hexdigest()[:16]


def _house():
    from spcopyro.synthetic import HouseSpec, make_house

    return make_house(seed=3, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=2))


def _result_arrays(result) -> dict[str, np.ndarray]:
    import json

    concepts = json.dumps(result.concepts(n_words=5), sort_keys=True)
    return {
        "labels_best": result.labels,
        "labels_final": result.labels_final,
        "pi": result.pi,
        "theta": result.theta,
        "w": result.w,
        "log_joint": result.trace.objective,
        "num_concepts": result.trace.num_concepts,
        "best_sweep": np.array([result.best_iteration]),
        "concepts": np.frombuffer(concepts.encode(), dtype=np.uint8),
    }


def fit_scenario(backend: str, preset_name: str, **options) -> dict[str, np.ndarray]:
    from spcopyro.config import preset
    from spcopyro.fit import fit_house
    from spcopyro.gibbs import GibbsOptions

    overrides = options.pop("overrides", {})
    gibbs = {k: overrides.pop(k) for k in ("cluster_moves", "unobserved_refresh") if k in overrides}
    gibbs["anneal_sweeps"] = options.pop("anneal_sweeps", 0)
    settings = preset(preset_name, **overrides)
    sampler = GibbsOptions(backend=backend, **gibbs)
    result = fit_house(_house(), settings, options=sampler, progress=False, **options)
    return _result_arrays(result)


def converged_scenario(backend: str, max_sweeps: int = 30) -> dict[str, np.ndarray]:
    from spcopyro.config import preset
    from spcopyro.fit import fit_house_converged
    from spcopyro.gibbs import GibbsOptions

    settings = preset("original-code", gamma=3.0, num_concepts=12)
    result, diagnostics = fit_house_converged(
        _house(),
        settings,
        chains=2,
        block=15,
        max_sweeps=max_sweeps,
        progress=False,
        options=GibbsOptions(backend=backend, anneal_sweeps=4),
    )
    arrays = _result_arrays(result)
    arrays["diag_log_joint"] = diagnostics.log_joint
    arrays["diag_best"] = np.array([diagnostics.best_chain])
    return arrays


def mcmc_scenario(backend: str) -> dict[str, np.ndarray]:
    import pyro
    from pyro.infer import MCMC

    from spcopyro.config import preset
    from spcopyro.fit import prepare_model_data
    from spcopyro.gibbs import GibbsOptions
    from spcopyro.gibbs.kernel import SpCoGibbs

    settings = preset("original-code", gamma=3.0, num_concepts=10)
    _, data = prepare_model_data(_house(), settings)
    pyro.set_rng_seed(7)
    kernel = SpCoGibbs(
        options=GibbsOptions(backend=backend, cluster_moves=0.5),
        anneal=True,
        save_params=("labels", "log_joint", "pi"),
    )
    mcmc = MCMC(kernel, num_samples=6, warmup_steps=4, disable_progbar=True)
    mcmc.run(data, settings.model)
    return {k: v.numpy() for k, v in mcmc.get_samples().items()}


def prior_scenario() -> dict[str, np.ndarray]:
    import pyro

    from spcopyro.config import preset
    from spcopyro.fit import prepare_model_data
    from spcopyro.simulate import sample_prior_world

    settings = preset("original-code", gamma=3.0, num_concepts=8, feature_scaling="floor100")
    _, data = prepare_model_data(_house(), settings)
    data = data.with_counts("words", data.word_counts.round())
    pyro.set_rng_seed(5)
    generator = torch.Generator().manual_seed(5)
    state, drawn = sample_prior_world(data, settings.model, generator, sweeps=20)
    return {
        "labels": state.labels.numpy(),
        "log_pi": state.log_pi.numpy(),
        "log_w": state.log_w.numpy(),
        "images": drawn.image_counts.numpy(),
        "words": drawn.word_counts.numpy(),
    }


def spcoa_scenario() -> dict[str, np.ndarray]:
    from spcopyro.baselines.spcoa import fit_spcoa

    result = fit_spcoa(_house(), num_concepts=10, iterations=20, seed=2)
    return {"labels": result.label_image(), "words": result.word_distribution(np.arange(50))}


SCENARIOS = {
    "fit-torch-paper-dp": lambda: fit_scenario("torch", "paper-dp", sweeps=25, seed=1),
    "fit-numba-paper-dp": lambda: fit_scenario("numba", "paper-dp", sweeps=25, seed=1),
    "fit-torch-options": lambda: fit_scenario(
        "torch",
        "original-code",
        sweeps=30,
        seed=4,
        chains=2,
        anneal_sweeps=8,
        init="gaussian",
        overrides=dict(gamma=3.0, num_concepts=20, cluster_moves=0.3, unobserved_refresh=0.4),
    ),
    "fit-numba-options": lambda: fit_scenario(
        "numba",
        "original-code",
        sweeps=30,
        seed=4,
        chains=2,
        anneal_sweeps=8,
        init="gaussian",
        overrides=dict(gamma=3.0, num_concepts=20, cluster_moves=0.3, unobserved_refresh=0.4),
    ),
    "fit-numba-dirichlet-tfidf": lambda: fit_scenario(
        "numba",
        "paper-dirichlet",
        sweeps=20,
        seed=2,
        overrides=dict(num_concepts=6, word_weighting="tfidf", use_images=False),
    ),
    "fit-torch-spcoa-init-8nbr": lambda: fit_scenario(
        "torch",
        "original-code",
        sweeps=15,
        seed=0,
        init="spcoa",
        overrides=dict(gamma=2.0, num_concepts=15, connectivity=8, use_words=False),
    ),
    "converged-torch": lambda: converged_scenario("torch"),
    "converged-numba": lambda: converged_scenario("numba"),
    "converged-torch-one-block": lambda: converged_scenario("torch", max_sweeps=15),
    "converged-numba-one-block": lambda: converged_scenario("numba", max_sweeps=15),
    "mcmc-torch": lambda: mcmc_scenario("torch"),
    "mcmc-numba": lambda: mcmc_scenario("numba"),
    "prior-world": prior_scenario,
    "spcoa": spcoa_scenario,
}
