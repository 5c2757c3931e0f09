"""Initial track states from plots: one-point and two-point differencing ([thesis] §3.5,
(3.25-3.27); the one-point initiation of the GNN baseline of [MZD] §5).

The single home of the initiation formulas. States are built in the constant-velocity
layout [x, vx, y, vy(, z, vz)] (m, m/s) and can be embedded in the common Singer layout
[x, vx, ax, y, vy, ay(, z, vz, az)] of [Dikić] eq. 22 by :func:`embed_common` (for the IMM and
the Singer/CA filters).

* Two-point: a plot z₁ and a later plot z₂, Δt apart, give per axis x̂ = [z₂, (z₂ − z₁)/Δt]
  and P = [[R₂, R₂/Δt], [R₂/Δt, (R₁ + R₂)/Δt²]] (the thesis's [[r, r/T], [r/T, 2r/T²]] for
  R₁ = R₂ = rI, re-ordered to the interleaved state).
* One-point: x̂ = [z, 0] per axis, P = diag(R, σ_v²) (the tracker uses σ_v² = v_max²/3, the
  variance of a Uniform(−v_max, v_max) velocity).
"""

from __future__ import annotations

import numpy as np


def interleave_covariance(Ppp: np.ndarray, Ppv: np.ndarray, Pvv: np.ndarray) -> np.ndarray:
    """Assemble (n, 2k, 2k) state covariances of the interleaved state [x, vx, y, vy, …]
    from position/position, position/velocity and velocity/velocity blocks (n, k, k)."""
    n, k, _ = Ppp.shape
    P = np.zeros((n, 2 * k, 2 * k))
    P[:, 0::2, 0::2] = Ppp
    P[:, 0::2, 1::2] = Ppv
    P[:, 1::2, 0::2] = Ppv.swapaxes(1, 2)
    P[:, 1::2, 1::2] = Pvv
    return P


def interleave_state(pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """[x, vx, y, vy, …] (n, 2k) from positions and velocities (n, k)."""
    n, k = pos.shape
    x = np.zeros((n, 2 * k))
    x[:, 0::2] = pos
    x[:, 1::2] = vel
    return x


def one_point(z: np.ndarray, R: np.ndarray, velocity_var: float) -> tuple[np.ndarray, np.ndarray]:
    """One-point CV states/covariances for plots z (n, k), R (n, k, k) or (k, k): zero
    velocity with variance ``velocity_var`` (m²/s²) per axis."""
    z = np.atleast_2d(np.asarray(z, float))
    n, k = z.shape
    R = np.broadcast_to(R, (n, k, k))
    zero = np.zeros((n, k, k))
    Pvv = np.broadcast_to(np.eye(k) * velocity_var, (n, k, k))
    return interleave_state(z, np.zeros_like(z)), interleave_covariance(R, zero, Pvv)


def two_point(
    z1: np.ndarray, R1: np.ndarray, z2: np.ndarray, R2: np.ndarray, dt
) -> tuple[np.ndarray, np.ndarray]:
    """Two-point differencing CV states/covariances at the time of z2 (3.25-3.27)."""
    z1, z2 = np.atleast_2d(z1), np.atleast_2d(z2)
    n, k = z2.shape
    # (the tracker passes per-plot arrays already: no broadcast views to build)
    R1 = R1 if np.shape(R1) == (n, k, k) else np.broadcast_to(R1, (n, k, k))
    R2 = R2 if np.shape(R2) == (n, k, k) else np.broadcast_to(R2, (n, k, k))
    dt = np.asarray(dt, dtype=np.float64)
    dt = dt if dt.shape == (n,) else np.broadcast_to(dt, (n,))
    x = interleave_state(z2, (z2 - z1) / dt[:, None])
    P = interleave_covariance(R2, R2 / dt[:, None, None], (R1 + R2) / dt[:, None, None] ** 2)
    return x, P


def embed_common(
    x: np.ndarray,
    P: np.ndarray,
    ndim: int,
    acceleration_sigma: float,
    unmeasured_var: tuple[float, float],
) -> tuple[np.ndarray, np.ndarray]:
    """CV-layout states over k measured axes → the common layout over ``ndim`` ≥ k axes:
    accelerations 0 ± ``acceleration_sigma`` (m/s²); an unmeasured axis (e.g. the height
    of a 2-D plot) gets position and velocity variances ``unmeasured_var``."""
    n, dk = x.shape
    k = dk // 2
    pos = [3 * a for a in range(k)]
    vel = [3 * a + 1 for a in range(k)]
    src = [i for pair in zip(pos, vel) for i in pair]  # common index of each CV entry
    xc = np.zeros((n, 3 * ndim))
    Pc = np.zeros((n, 3 * ndim, 3 * ndim))
    xc[:, src] = x
    Pc[np.ix_(np.arange(n), src, src)] = P
    for a in range(ndim):
        Pc[:, 3 * a + 2, 3 * a + 2] = acceleration_sigma**2
        if a >= k:
            Pc[:, 3 * a, 3 * a], Pc[:, 3 * a + 1, 3 * a + 1] = unmeasured_var
    return xc, Pc
