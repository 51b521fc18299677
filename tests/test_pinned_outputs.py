"""Seeded outputs pinned before the inference-interface refactor (issue 9): behaviour unchanged.

The first pins (then digests in this file) were recorded on main at 6278b5e, before any of the
refactor's changes, by running :data:`pinned_runs.SCENARIOS` (fits with both backends and the
stability options, the ``--sweeps auto`` driver, Pyro's MCMC with the kernel, a prior draw, the
SpCoA baseline). A change that alters any label, concept table or trace of these runs fails here.
If a change of behaviour is intended, say so in the commit and record the new pins
(``python tests/pinned_runs.py --record [SCENARIO ...]``, see :mod:`pinned_runs`).

One change was intended (issue 9): ``--sweeps auto`` used to restart every block from the last
labels with freshly drawn globals; it now continues each chain from its whole state (labels,
globals, generator). Its two-block runs ``converged-*`` therefore have new digests (recorded after
the change); the one-block runs ``converged-*-one-block``, whose digests were computed with the
code of 6278b5e, show that everything up to the first block boundary is unchanged.

A second intended change (issue 14, readable word lists): a Gibbs result reports the posterior
means of pi, theta and w given its labels (:mod:`spcopyro.results.posterior_means`) instead of the
best state's draws, and ``concepts()`` gains keys. The ``fit-*`` and ``converged-*`` digests were
recorded again after that change; their labels and traces are unchanged (only the concept tables
and summaries differ), and the ``mcmc-*``, ``prior-world`` and ``spcoa`` digests are untouched.

A third intended change (issue 15, the lean compiled kernel): the numba backend draws its labels
in another order inside each colour block, pi's background by the alias method and its gamma
variates from another use of its random stream, so the ``*-numba*`` digests were recorded again;
the torch digests are untouched. Its distribution is what the distribution tests check.

A fourth change, of the pinning only (issue 22, item 11: pins that hold on any machine): the
digests hashed floats as 12-significant-digit text, and the six ``*-numba*`` ones failed on an
AMD EPYC (znver4, AVX-512) while passing where they were recorded. The compiled log joint sums
with ``fastmath`` reassociation and contraction, so its last bits follow the CPU target (vector
width, FMA): run here natively and with ``NUMBA_CPU_NAME`` generic, haswell and skylake-avx512,
every scenario gave identical integer arrays, bit-identical posterior means and concept tables,
and log joints up to 5.9e-11 apart relative (fit-numba-paper-dp, generic against skylake-avx512:
1.3e-5 on 2.2e5; mcmc-numba: 4.2e-12); torch's log joints move the same way with
``ATEN_CPU_CAPABILITY=default`` (up to 1.6e-11). The old digests all held under skylake-avx512
here, so the labels are those recorded before. Integer arrays are now pinned exactly (a digest in
``pinned_outputs.json``, which also covers every array's name and shape), float arrays (the
numbers of the ``concepts()`` table among them, its text pinned exactly without them) as
reference values in ``pinned_outputs.npz`` compared to a relative 1e-9 (see :mod:`pinned_runs`).
All pins were recorded again on that machine; no scenario's behaviour changed.

A fifth change (issue 23): ``fit-numba-options`` failed on an AMD EPYC with AVX2 only (znver2)
while passing on the AVX-512 machine of its pin. Its labels, traces and floats were identical; the
concept table's word order was not: two words with the same counts (sofa, tv) tie in lift, and
the lift's denominator, a matrix product, differs in its last bits between columns under the
BLAS kernel OpenBLAS picks for the CPU (``OPENBLAS_CORETYPE=Nehalem`` gave the old pin here, every
other kernel the other order). Words are now ranked after rounding to 1e-9, ties in item order
(:func:`spcopyro.results.concept_words.ranked`): the same digest under every OpenBLAS kernel tried
(Haswell, Sandybridge, Nehalem, Prescott). Only that scenario's pin was recorded again.

A sixth intended change (2026-12-04): :func:`spcopyro.simulate.sample_prior_world` draws the
counts under a seed taken from its generator instead of from torch's global RNG (two calls with
equally seeded generators gave the same labels and other counts; notebook 1 did not reproduce
its stored outputs). The ``prior-world`` scenario's labels, pi and w are unchanged (its digest
too); its drawn image and word counts were recorded again. They are drawn by the same model
call as before (:func:`spcopyro.simulate.sample_observations`), from another stream;
``test_prior_world_has_regions_above_the_critical_coupling`` checks their totals and that the
generator alone decides them.

A seventh intended change (2026-12-05, afcd6ce): ``concepts()`` gains a ``name`` per concept
(the word whose ``where`` answer the concept is, :mod:`spcopyro.results.concept_names`), so the
ten ``fit-*`` and ``converged-*`` concept tables are longer and their digests were recorded again.
Checked before recording: every array of every scenario, run at bcf81ba (before the change) and
at d1b3738, is identical (floats bit for bit) except the concept tables, whose text differs only
by the added ``"name": ...`` entries. The stored floats (``pinned_outputs.npz``) were kept.
The name then became the most probable of those words in the concept (p(word | concept), not
p(C | word)): every scenario run with both rules gave identical arrays except the concept text,
differing only in four names (fit-torch-paper-dp: shower -> bathroom; fit-torch-options: sink ->
kitchen; converged-numba-one-block: table -> bedroom, sink -> kitchen), and the old rule's tables
gave the stored digests; those three digests were recorded again, the floats kept.

An eighth intended change (2026-12-06): a fit that did not model its words (``use_words`` off)
lists no words for its concepts: ``concepts()`` gives it empty ``top_words`` and a ``words_note``
"words not modelled (use_words off)", and names its concepts ``concept N``
(:mod:`spcopyro.results.concept_names`), where it listed five words tied at the prior's
probability and named every concept "kitchen" by tie order. Of the scenarios only
``fit-torch-spcoa-init-8nbr`` (``use_words=False``) fits so; checked before recording, its
arrays are identical to those before the change but for the concept table (its text differs
only in those three keys of the four concepts that heard words; its numbers lose the 20 tied
probabilities, the rest equal), and its digest and floats were recorded again.

Not a change (issue 25, item 4): the compiled sweep can draw its globals' label-free gamma
variates ahead, on a worker thread (:mod:`spcopyro.gibbs.numba_globals`, ``SPCOPYRO_PRIOR_THREAD``
= auto, on or off), which consumes other random numbers; it is opt-in, so every pin holds under
the default one-pass draw. (With the two-part draw the five numba scenarios that sweep with
``unobserved_refresh`` = 1 give other digests, the same with the worker on and off.)
"""

from __future__ import annotations

import numpy as np
import pytest
from pinned_runs import ATOL, RTOL, SCENARIOS, digest, float_arrays, load_pins

DIGESTS, FLOATS = load_pins()


def test_every_scenario_is_pinned():
    assert set(DIGESTS) == set(SCENARIOS)
    assert set(FLOATS) == set(SCENARIOS)


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_seeded_outputs_are_unchanged(name):
    if "numba" in name:
        pytest.importorskip("numba")
    arrays = SCENARIOS[name]()
    # Names, shapes and integer values exactly (labels, counts, the concept table's text).
    assert digest(arrays) == DIGESTS[name]
    floats = float_arrays(arrays)
    assert set(floats) == set(FLOATS[name])
    for key, recorded in FLOATS[name].items():
        np.testing.assert_allclose(
            floats[key], recorded, rtol=RTOL, atol=ATOL, err_msg=f"{name}: {key}"
        )
