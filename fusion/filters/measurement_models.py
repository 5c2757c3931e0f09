"""Measurement models for the batched (E)KF: ``predict(x) -> (ẑ (n, m), H (n, m, d))`` and
``residual(z, ẑ)``.

* :class:`PositionMeasurement` — converted measurements ([Dikić] eq. 7-12): z = H x + v with H
  picking the position components (x east, y north[, z up]); R per plot from
  :func:`fusion.frames.convert_plots`.
* :class:`PolarMeasurement` — the EKF alternative of [Dikić] (eq. 13-14, with the
  elevation formula corrected): relative to a sensor at position s in the frame,
  2-D h(x) = [ρ, ψ] with ρ = √(Δx² + Δy²), ψ = atan2(Δx, Δy) (clockwise from north);
  3-D h(x) = [D, ψ, θ], D = |Δ|, θ = atan2(Δz, ρ). The azimuth residual is wrapped to
  (−π, π]. Exact in ``planar`` and ``ned`` frames near the sensor; in a stereographic
  plane it neglects the grid convergence and scale at the sensor.
"""

from __future__ import annotations

import numpy as np


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Wrap angles to (−π, π]."""
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


class PositionMeasurement:
    """Linear position measurement of a model (uses its ``position_index``)."""

    def __init__(self, model, ndim: int | None = None) -> None:
        idx = list(model.position_index)
        self.ndim = len(idx) if ndim is None else ndim
        self.H = np.zeros((self.ndim, model.dim))
        self.H[np.arange(self.ndim), idx[: self.ndim]] = 1.0

    def predict(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = x.shape[0]
        return x @ self.H.T, np.broadcast_to(self.H, (n, *self.H.shape))

    @staticmethod
    def residual(z: np.ndarray, zhat: np.ndarray) -> np.ndarray:
        return z - zhat


class PolarMeasurement:
    """Polar measurement from a sensor at ``sensor_position`` (ndim,) in the frame."""

    def __init__(self, model, sensor_position, ndim: int = 2) -> None:
        if ndim not in (2, 3):
            raise ValueError(f"ndim = {ndim}: must be 2 (range, azimuth) or 3 (+ elevation)")
        self.ndim = ndim
        self.pos_idx = list(model.position_index)[:ndim]
        if len(self.pos_idx) < ndim:
            raise ValueError(f"model {type(model).__name__} has no {ndim}-D position")
        self.dim = model.dim
        self.sensor = np.asarray(sensor_position, float)[:ndim]

    def predict(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = x[:, self.pos_idx] - self.sensor
        dx, dy = d[:, 0], d[:, 1]
        rho2 = np.maximum(dx * dx + dy * dy, 1e-12)
        rho = np.sqrt(rho2)
        n = x.shape[0]
        H = np.zeros((n, self.ndim, self.dim))
        ix, iy = self.pos_idx[0], self.pos_idx[1]
        az = np.mod(np.arctan2(dx, dy), 2 * np.pi)
        if self.ndim == 2:
            H[:, 0, ix], H[:, 0, iy] = dx / rho, dy / rho
            H[:, 1, ix], H[:, 1, iy] = dy / rho2, -dx / rho2
            return np.column_stack([rho, az]), H
        dz = d[:, 2]
        iz = self.pos_idx[2]
        D2 = rho2 + dz * dz
        D = np.sqrt(D2)
        H[:, 0, ix], H[:, 0, iy], H[:, 0, iz] = dx / D, dy / D, dz / D
        H[:, 1, ix], H[:, 1, iy] = dy / rho2, -dx / rho2
        H[:, 2, ix] = -dx * dz / (D2 * rho)
        H[:, 2, iy] = -dy * dz / (D2 * rho)
        H[:, 2, iz] = rho / D2
        return np.column_stack([D, az, np.arctan2(dz, rho)]), H

    @staticmethod
    def residual(z: np.ndarray, zhat: np.ndarray) -> np.ndarray:
        nu = z - zhat
        nu[..., 1] = wrap_angle(nu[..., 1])
        return nu
