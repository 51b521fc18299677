"""What a fit hands back and what users query: :class:`~spcopyro.results.result.SpCoResult`
(the semantic map, words per concept, "where is X?"), the semantic-map protocol every method and
baseline is scored through, posterior means, the point estimate of the labels, uncertainty maps,
concept words and the degenerate-map check. Reading a saved result needs numpy only."""
