"""The paper's comparison (Table 4, Figs. 5-7) as one command: ``spcopyro experiment``.

* :mod:`spcopyro.experiments.methods`: the compared methods (A), (A'), (B), (C)-(F), each fitted
  to a house and returned as a :class:`~spcopyro.results.semantic_map.SemanticMapModel`.
* :mod:`spcopyro.experiments.table`: scores on synthetic houses (ARI, matching rate) and on the
  public houses (held-out-trial word prediction and localisation); ``table.md`` / ``table.json``.
* :mod:`spcopyro.experiments.figures`: ARI and concepts per sweep, the maps side by side.
* :mod:`spcopyro.experiments.cli`: the ``experiment`` and ``compare-inference`` commands.
"""
