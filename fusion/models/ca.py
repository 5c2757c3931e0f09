"""Nearly constant acceleration (CA / white-noise jerk) ([Dikić] eq. 3-4).

Per axis the state is [p, v, a] with F_T = [[1, T, T²/2], [0, 1, T], [0, 0, 1]] and the
process covariance of a continuous white jerk of spectral density q (m²/s⁵):
Q_T = q [[T⁵/20, T⁴/8, T³/6], [T⁴/8, T³/3, T²/2], [T³/6, T²/2, T]] (Bar-Shalom et al.
2001, §6.2.3). Interleaved state [x, vx, ax, y, vy, ay(, z, vz, az)], metres, m/s, m/s².
This is also the αT → 0 limit of the Singer model (:mod:`fusion.models.singer`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import as_dt_array

AXIS_LABELS = (("x", "vx", "ax"), ("y", "vy", "ay"), ("z", "vz", "az"))


def ca_axis_F(t: np.ndarray) -> np.ndarray:
    """(n, 3, 3) per-axis CA transition for an array of dt."""
    F = np.zeros((t.size, 3, 3))
    F[:, 0, 0] = F[:, 1, 1] = F[:, 2, 2] = 1.0
    F[:, 0, 1] = F[:, 1, 2] = t
    F[:, 0, 2] = t * t / 2
    return F


def ca_axis_Q(t: np.ndarray, q: float) -> np.ndarray:
    """(n, 3, 3) per-axis white-jerk process covariance, spectral density q."""
    Q = np.empty((t.size, 3, 3))
    Q[:, 0, 0] = t**5 / 20
    Q[:, 0, 1] = Q[:, 1, 0] = t**4 / 8
    Q[:, 0, 2] = Q[:, 2, 0] = t**3 / 6
    Q[:, 1, 1] = t**3 / 3
    Q[:, 1, 2] = Q[:, 2, 1] = t**2 / 2
    Q[:, 2, 2] = t
    return q * Q


def block_diag_axes(blocks: list[np.ndarray]) -> np.ndarray:
    """Place per-axis (n, k, k) blocks on the diagonal of an (n, K, K) array."""
    n, k = blocks[0].shape[0], blocks[0].shape[1]
    out = np.zeros((n, k * len(blocks), k * len(blocks)))
    for a, b in enumerate(blocks):
        out[:, a * k : (a + 1) * k, a * k : (a + 1) * k] = b
    return out


class PositionVelocityAcceleration:
    """State layout shared by CA and Singer: ``[x, vx, ax, y, vy, ay(, z, vz, az)]`` over
    ``self.ndim`` axes (metres, m/s, m/s²)."""

    ndim: int

    def _check_ndim(self) -> None:
        if self.ndim not in (1, 2, 3):
            raise ValueError(f"ndim = {self.ndim}: must be 1, 2 or 3")

    @property
    def dim(self) -> int:
        return 3 * self.ndim

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(lab for ax in AXIS_LABELS[: self.ndim] for lab in ax)

    @property
    def position_index(self) -> tuple[int, ...]:
        return tuple(range(0, self.dim, 3))


@dataclass(frozen=True)
class ConstantAcceleration(PositionVelocityAcceleration):
    """CA model over ``ndim`` axes (1, 2 or 3); q: jerk spectral density, m²/s⁵."""

    q: float = 1.0
    ndim: int = 2
    q_vertical: float | None = None

    def __post_init__(self) -> None:
        self._check_ndim()
        if not self.q >= 0:
            raise ValueError(f"q = {self.q}: must be >= 0 m²/s⁵")

    def F(self, dt: float | np.ndarray) -> np.ndarray:
        t, scalar = as_dt_array(dt)
        F = block_diag_axes([ca_axis_F(t)] * self.ndim)
        return F[0] if scalar else F

    def Q(self, dt: float | np.ndarray) -> np.ndarray:
        t, scalar = as_dt_array(dt)
        qs = [self.q] * self.ndim
        if self.ndim == 3 and self.q_vertical is not None:
            qs[2] = self.q_vertical
        Q = block_diag_axes([ca_axis_Q(t, q) for q in qs])
        return Q[0] if scalar else Q

    def H(self) -> np.ndarray:
        H = np.zeros((self.ndim, self.dim))
        H[np.arange(self.ndim), list(self.position_index)] = 1.0
        return H
