"""spcopyro: SpCoMapping (Katsumata et al., 2019) as a Pyro program with a fast Gibbs kernel."""

__version__ = "0.1.0"
