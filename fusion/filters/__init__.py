"""Filters batched over many tracks/components: states ``(n, d)``, covariances ``(n, d, d)``."""
