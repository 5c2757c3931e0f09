"""Track densities of the existence trackers behind one interface (:mod:`.base`):
Gaussian mixtures with Singer N-scan memory (:mod:`.gaussian_mixture`) and IMM mixtures
(:mod:`.imm_mixture`)."""

from .base import GatedTable, Prediction, TrackDensity
from .gaussian_mixture import GaussianMixtureDensity

__all__ = ["GatedTable", "GaussianMixtureDensity", "Prediction", "TrackDensity"]
