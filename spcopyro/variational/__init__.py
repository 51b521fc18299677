"""Variational inference for SpCoMapping: mean-field coordinate ascent (CAVI) over the global
Dirichlet factors and per-cell q(C), its ELBO, and the run loop other label-field updates (loopy
belief propagation, a compiled backend) plug into. The Pyro guide for ``pyro.infer.SVI`` is in
:mod:`spcopyro.guides`."""
