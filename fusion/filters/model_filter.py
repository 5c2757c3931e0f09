"""Single-model batched filters over many tracks: the converted-measurement KF and the
polar-measurement EKF ([Dikić] eq. 7-14).

Both are :class:`ModelFilter` = a motion model (:mod:`fusion.models`) + a measurement
model (:mod:`fusion.filters.measurement_models`), operating on a
:class:`~fusion.filters.gaussian_state.GaussianState` of n tracks at once. The
converted-measurement KF takes plots converted by :func:`fusion.frames.convert_plots`
(position z and its per-plot covariance R in the system frame); the polar EKF takes the
raw (range, azimuth[, elevation]) with R_s = diag(σ²).
"""

from __future__ import annotations

import numpy as np

from . import ekf
from .gaussian_state import GaussianState
from .kalman import gaussian_log_likelihood
from .measurement_models import PolarMeasurement, PositionMeasurement


class ModelFilter:
    """A batched (E)KF for one motion model and one measurement model."""

    def __init__(self, model, measurement, name: str | None = None) -> None:
        self.model = model
        self.measurement = measurement
        self.name = name or type(model).__name__

    @property
    def dim(self) -> int:
        return self.model.dim

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(self.model.labels)

    def predict(self, state: GaussianState, dt) -> GaussianState:
        """Predict all tracks over dt (s; scalar or (n,))."""
        return GaussianState(*ekf.predict(self.model, state.x, state.P, dt))

    def predict_measurement(self, state: GaussianState, R) -> tuple[np.ndarray, np.ndarray]:
        """ẑ (n, m) and S = H P Hᵀ + R (n, m, m) for gating."""
        zhat, _, S = ekf.innovation(state.x, state.P, R, self.measurement)
        return zhat, S

    def update(self, state: GaussianState, z, R):
        """Update track i with measurement z[i] (covariance R[i] or shared R).
        Returns (state, ν, S, log N(ν; 0, S))."""
        x, P, nu, S = ekf.update(state.x, state.P, z, R, self.measurement)
        return GaussianState(x, P), nu, S, gaussian_log_likelihood(nu, S)

    def position(self, state: GaussianState) -> np.ndarray:
        return state.x[:, list(self.model.position_index)]


def ConvertedMeasurementKF(model, name: str | None = None) -> ModelFilter:
    """Linear KF on converted position measurements ([Dikić] eq. 7-12), per-plot R."""
    return ModelFilter(model, PositionMeasurement(model), name)


def PolarEKF(model, sensor_position, ndim: int = 2, name: str | None = None) -> ModelFilter:
    """EKF with the polar h(x) of a sensor at ``sensor_position`` ([Dikić] eq. 13-14)."""
    return ModelFilter(model, PolarMeasurement(model, sensor_position, ndim), name)
