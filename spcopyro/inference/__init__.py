"""What every inference method shares: the method protocol and its outputs
(:mod:`~spcopyro.inference.protocol`), the label starts
(:mod:`~spcopyro.inference.initialisation`), the annealing schedule and the stopping rule
(:mod:`~spcopyro.inference.schedule`), and the run loop of the iterative variational methods,
each an ``init`` / ``step`` pair (:mod:`~spcopyro.inference.driver`).
The methods themselves are in :mod:`spcopyro.gibbs` (the sampler) and :mod:`spcopyro.guides`
(variational inference); :mod:`spcopyro.fit.registry` lists them by name."""
