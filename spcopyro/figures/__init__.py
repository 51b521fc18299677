"""Figures of a fit: the semantic map, "where is X?" answers, traces and uncertainty
(:mod:`~spcopyro.figures.plotting`; the house in :mod:`~spcopyro.figures.house`, the trace in
:mod:`~spcopyro.figures.trace`), and the map's words, legend and outlines they are built from
(:mod:`~spcopyro.figures.map_pieces`)."""
