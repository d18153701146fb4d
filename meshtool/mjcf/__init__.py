"""MuJoCo models of assets: the neutral model description, the models written, and the load check."""
