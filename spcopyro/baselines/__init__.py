"""The comparison methods of the SpCoMapping paper (Katsumata et al. 2019, Table 4), each in one
module, each giving a semantic map scored by :mod:`spcopyro.metrics`:

* :mod:`spcopyro.baselines.spcoa` (C): spatial concept formation with words (SpCoA style).
* :mod:`spcopyro.baselines.cnn` (D): CNN-based semantic mapping (Suenderhauf et al. 2016).
* :mod:`spcopyro.baselines.nearest` (E): every cell takes the word of the nearest utterance.
* :mod:`spcopyro.baselines.geometry` (F): room segmentation of the occupancy map alone
  (distance-transform segmentation, Bormann et al. 2016).
"""
