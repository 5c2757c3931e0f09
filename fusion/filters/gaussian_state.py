"""Batched Gaussian track states: ``x`` (n, d), ``P`` (n, d, d).

A small container (shapes checked) so that the single-model filters of
:mod:`fusion.filters.model_filter` work on arrays over all tracks."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class GaussianState:
    """Means x (n, d) and covariances P (n, d, d) of n tracks, in the model's state order."""

    x: np.ndarray
    P: np.ndarray

    def __post_init__(self) -> None:
        self.x = np.atleast_2d(np.asarray(self.x, float))
        self.P = np.asarray(self.P, float)
        d = self.x.shape[1]
        if self.P.shape != (self.x.shape[0], d, d):
            self.P = self.P.reshape(self.x.shape[0], d, d)
        if self.P.shape[-1] != d:
            raise ValueError(f"P has shape {self.P.shape} but x has shape {self.x.shape}")

    def __len__(self) -> int:
        return self.x.shape[0]
