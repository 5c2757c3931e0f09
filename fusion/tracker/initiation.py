"""Track initiation from plots no existing track selected (spec 02 §5, spec 03 §2).

* Two-point differencing (3.25-3.27): a plot z₁ kept from an earlier batch and a new plot
  z₂ with ‖z₂ − z₁‖ ≤ v_max Δt start a track with, per axis, x̂ = [z₂, (z₂ − z₁)/Δt] and
  P = [[R₂, R₂/Δt], [R₂/Δt, (R₁ + R₂)/Δt²]] (the thesis's [[r, r/T], [r/T, 2r/T²]] for
  R₁ = R₂ = rI, re-ordered to the interleaved state).
* One-point: x̂ = [z, 0] per axis, P = diag(R, v_max²/3) (variance of a Uniform(−v_max,
  v_max) velocity).

Unused plots wait in a :class:`PlotBuffer` for ``max_dt`` seconds; a buffered plot that
forms pairs is consumed by them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .gating import window_pairs


def interleave_covariance(Ppp: np.ndarray, Ppv: np.ndarray, Pvv: np.ndarray) -> np.ndarray:
    """Assemble (n, 2k, 2k) state covariances of the interleaved state [x, vx, y, vy, …]
    from position/position, position/velocity and velocity/velocity blocks (n, k, k)."""
    n, k, _ = Ppp.shape
    P = np.zeros((n, 2 * k, 2 * k))
    P[:, 0::2, 0::2] = Ppp
    P[:, 0::2, 1::2] = Ppv
    P[:, 1::2, 0::2] = np.swapaxes(Ppv, 1, 2)
    P[:, 1::2, 1::2] = Pvv
    return P


def interleave_state(pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
    n, k = pos.shape
    x = np.zeros((n, 2 * k))
    x[:, 0::2] = pos
    x[:, 1::2] = vel
    return x


def one_point(z: np.ndarray, R: np.ndarray, v_max: float) -> tuple[np.ndarray, np.ndarray]:
    """One-point initial states and covariances for plots z (n, k), R (n, k, k)."""
    n, k = z.shape
    zero = np.zeros((n, k, k))
    Pvv = np.broadcast_to(np.eye(k) * v_max**2 / 3.0, (n, k, k))
    return interleave_state(z, np.zeros_like(z)), interleave_covariance(R, zero, Pvv)


def two_point(
    z1: np.ndarray, R1: np.ndarray, z2: np.ndarray, R2: np.ndarray, dt: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Two-point differencing states/covariances at the time of z2 (3.25-3.27)."""
    dt = np.asarray(dt, dtype=np.float64)
    x = interleave_state(z2, (z2 - z1) / dt[:, None])
    P = interleave_covariance(R2, R2 / dt[:, None, None], (R1 + R2) / dt[:, None, None] ** 2)
    return x, P


@dataclass
class PlotBuffer:
    """Plots not selected by any track, waiting for a two-point partner."""

    z: np.ndarray
    R: np.ndarray
    time: np.ndarray  # ns
    uid: np.ndarray

    @classmethod
    def empty(cls, k: int) -> PlotBuffer:
        return cls(
            np.zeros((0, k)), np.zeros((0, k, k)), np.zeros(0, np.int64), np.zeros(0, np.int64)
        )

    def __len__(self) -> int:
        return len(self.time)

    def keep(self, mask: np.ndarray) -> None:
        self.z, self.R, self.time, self.uid = (
            self.z[mask],
            self.R[mask],
            self.time[mask],
            self.uid[mask],
        )

    def add(self, z: np.ndarray, R: np.ndarray, time: np.ndarray, uid: np.ndarray) -> None:
        self.z = np.concatenate([self.z, z])
        self.R = np.concatenate([self.R, R])
        self.time = np.concatenate([self.time, time])
        self.uid = np.concatenate([self.uid, uid])


def pair_plots(
    buffer: PlotBuffer,
    z: np.ndarray,
    time: np.ndarray,
    v_max: float,
    min_dt: float,
    max_dt: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs (buffer index, new plot index, Δt s) with min_dt ≤ Δt ≤ max_dt and
    ‖z₂ − z₁‖ ≤ v_max Δt (the maximum-velocity criterion of spec 02 §5)."""
    if len(buffer) == 0 or len(z) == 0:
        e = np.zeros(0, np.int64)
        return e, e, np.zeros(0)
    radius = np.full(len(z), v_max * max_dt)
    new_i, old_j = window_pairs(z, radius, buffer.z)
    dt = (time[new_i] - buffer.time[old_j]) * 1e-9
    dist = np.linalg.norm(z[new_i] - buffer.z[old_j], axis=1)
    ok = (dt >= min_dt) & (dt <= max_dt) & (dist <= v_max * dt)
    return old_j[ok], new_i[ok], dt[ok]
