"""The paper's comparison (Table 4, Figs. 5-7) and its side studies; ``spcopyro experiment``
runs the comparison as the shipped study ``experiment`` (:mod:`spcopyro.study.experiment`).

* :mod:`spcopyro.experiments.methods`: the compared methods (A), (A'), (B), (C)-(F), each fitted
  to a house and returned as a :class:`~spcopyro.results.semantic_map.SemanticMapModel`.
* :mod:`spcopyro.experiments.table`: scores on synthetic houses (ARI, matching rate) and on the
  public houses (held-out-trial word prediction and localisation); ``table.md`` / ``table.json``.
* :mod:`spcopyro.experiments.figures`: the stability study's figure.
"""
