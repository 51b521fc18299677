"""Figures of a fit: the semantic map, "where is X?" answers, traces and uncertainty
(:mod:`~spcopyro.figures.plotting`), and the map's words, legend and outlines they are built from
(:mod:`~spcopyro.figures.map_pieces`)."""
