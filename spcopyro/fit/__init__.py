"""Fitting a house end to end: data preparation, the inference method by name
(:mod:`~spcopyro.fit.registry`), the Gibbs chains of a fit (:mod:`~spcopyro.fit.gibbs_chains`)
and :func:`~spcopyro.fit.house.fit_house`, which returns a
:class:`~spcopyro.results.result.SpCoResult`."""
