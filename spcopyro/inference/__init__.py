"""What every inference method shares: the method protocol and its outputs
(:mod:`~spcopyro.inference.protocol`) and the label starts
(:mod:`~spcopyro.inference.initialisation`).
The methods themselves are in :mod:`spcopyro.gibbs` (the sampler) and :mod:`spcopyro.guides`
(variational inference); :mod:`spcopyro.fit.registry` lists them by name."""
