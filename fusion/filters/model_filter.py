"""Single-model batched filters over many tracks: the converted-measurement KF and the
polar-measurement EKF (spec 01 §2), plus track initiation.

Both are :class:`ModelFilter` = a motion model (:mod:`fusion.models`) + a measurement
model (:mod:`fusion.filters.measurement_models`), operating on a
:class:`~fusion.filters.gaussian_state.GaussianState` of n tracks at once. The
converted-measurement KF takes plots converted by :func:`fusion.frames.convert_plots`
(position z and its per-plot covariance R in the system frame); the polar EKF takes the
raw (range, azimuth[, elevation]) with R_s = diag(σ²).
"""

from __future__ import annotations

import numpy as np

from ..models import CoordinatedTurn, from_common, to_common
from . import ekf
from .gaussian_state import GaussianState
from .initiation import embed_common, one_point, two_point
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

    # --- common (Singer-layout) format, for IMM mixing and initiation ---------------------
    def to_common(self, x, P):
        return to_common(self.model, x, P)

    def from_common(self, x, P):
        return from_common(self.model, x, P)

    def initiate(self, z, R, *, velocity_sigma: float = 300.0, acceleration_sigma: float = 10.0):
        """One-point initiation from position measurements z (n, m), R (n, m, m): zero
        velocity (σ = velocity_sigma m/s) and acceleration (σ = acceleration_sigma m/s²)."""
        z = np.atleast_2d(np.asarray(z, float))
        R = np.broadcast_to(R, (z.shape[0], z.shape[1], z.shape[1]))
        if isinstance(self.model, CoordinatedTurn):
            n, m = z.shape
            x = np.zeros((n, self.dim))
            P = np.zeros((n, self.dim, self.dim))
            pi = list(self.model.position_index)[:m]
            x[:, pi] = z
            P[np.ix_(np.arange(n), pi, pi)] = R
            P[:, 2, 2] = np.pi**2
            P[:, 3, 3] = self.model.sigma_omega**2 * 100
            P[:, 4, 4] = velocity_sigma**2
            if self.model.vertical:
                P[:, 6, 6] = velocity_sigma**2
            return GaussianState(x, P)
        xc, Pc = common_one_point(z, R, velocity_sigma, acceleration_sigma, self.model.ndim)
        return GaussianState(*self.from_common(xc, Pc))

    def initiate_two_point(self, z1, R1, z2, R2, dt, *, acceleration_sigma: float = 10.0):
        """Two-point differencing: position z2, velocity (z2 − z1)/dt (Bar-Shalom)."""
        xc, Pc = common_two_point(z1, R1, z2, R2, dt, acceleration_sigma, self.model.ndim)
        return GaussianState(*self.from_common(xc, Pc))


def ConvertedMeasurementKF(model, name: str | None = None) -> ModelFilter:
    """Linear KF on converted position measurements (spec 01 §2), per-plot R."""
    return ModelFilter(model, PositionMeasurement(model), name)


def PolarEKF(model, sensor_position, ndim: int = 2, name: str | None = None) -> ModelFilter:
    """EKF with the polar measurement h(x) of a sensor at ``sensor_position`` (spec 01 §2)."""
    return ModelFilter(model, PolarMeasurement(model, sensor_position, ndim), name)


def common_one_point(z, R, velocity_sigma, acceleration_sigma, ndim):
    """Common-format (Singer layout, ``ndim`` axes) state from one position measurement
    (:func:`fusion.filters.initiation.one_point` embedded by ``embed_common``)."""
    x, P = one_point(z, R, velocity_sigma**2)
    return embed_common(x, P, ndim, acceleration_sigma, (1e8, velocity_sigma**2))


def common_two_point(z1, R1, z2, R2, dt, acceleration_sigma, ndim):
    """Two-point differencing in the common format: p = z2, v = (z2 − z1)/dt,
    Cov = [[R2, R2/dt], [R2/dt, (R1 + R2)/dt²]] (acceleration 0 ± acceleration_sigma)."""
    x, P = two_point(z1, R1, z2, R2, dt)
    return embed_common(x, P, ndim, acceleration_sigma, (1e8, 1e4))
