"""State conversions to and from the common (Singer-format) state of the three-model
IMM, spec 01 §4 (004 eq. 22), with covariances by the Jacobian of each conversion.

Common format: [x, vx, ax, y, vy, ay(, z, vz, az)] (the Singer/CA layout).
* CV [x, vx, y, vy(, z, vz)] → common: accelerations a = 0 with zero variance; back:
  drop the accelerations (004: "CV states get a_x = a_y = 0").
* CT (x, y, ψ, ω, v(, z, vz)) → common: v_x = v cosψ, v_y = v sinψ, a_x = −ω v_y,
  a_y = ω v_x (004 eq. 22); back: ψ = atan2(v_y, v_x), v = |v|, ω = (v_x a_y − v_y a_x)/v²
  (when |v| is within 3σ of zero, course and turn rate get an uninformative covariance).
  The vertical channel (z, vz) maps to (z, vz, az = 0).
* Singer/CA: identity.
"""

from __future__ import annotations

import numpy as np

from .ca import ConstantAcceleration
from .coordinated_turn import CoordinatedTurn
from .cv import ConstantVelocity
from .singer import Singer

_MIN_SPEED = 1e-3  # m/s, below it the course of a CT state is undefined
SPEED_SIGNIFICANCE = 3.0
"""CT course/turn rate are linearised only when |v| > 3 σ_v; below, uninformative."""


def _sandwich(J, P):
    out = J @ P @ J.swapaxes(-1, -2)
    return 0.5 * (out + out.swapaxes(-1, -2))


def common_dim(ndim: int) -> int:
    return 3 * ndim


def _cv_common_index(ndim: int) -> np.ndarray:
    """Where the CV entries [x, vx, y, vy(, z, vz)] sit in the common layout (the
    embedding x_c = S x with the 0/1 selector S, whose non-zero rows these are)."""
    return np.array([3 * a + b for a in range(ndim) for b in (0, 1)])


def to_common(model, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Model-native states (n, d), covariances (n, d, d) → common format."""
    if isinstance(model, (Singer, ConstantAcceleration)):
        return x, P
    if isinstance(model, ConstantVelocity):
        # S x and S P Sᵀ are placements of x and P (exact)
        idx = _cv_common_index(model.ndim)
        xc = np.zeros((len(x), 3 * model.ndim))
        xc[:, idx] = x
        Pc = np.zeros((len(x), 3 * model.ndim, 3 * model.ndim))
        Pc[:, idx[:, None], idx[None, :]] = 0.5 * (P + P.swapaxes(-1, -2))
        return xc, Pc
    if isinstance(model, CoordinatedTurn):
        n = x.shape[0]
        ndim = model.ndim
        psi, w, v = x[:, 2], x[:, 3], x[:, 4]
        c, s = np.cos(psi), np.sin(psi)
        vx, vy = v * c, v * s
        xc = np.zeros((n, 3 * ndim))
        xc[:, 0], xc[:, 1], xc[:, 2] = x[:, 0], vx, -w * vy
        xc[:, 3], xc[:, 4], xc[:, 5] = x[:, 1], vy, w * vx
        J = np.zeros((n, 3 * ndim, model.dim))
        J[:, 0, 0] = 1.0
        J[:, 1, 2], J[:, 1, 4] = -vy, c
        J[:, 2, 2], J[:, 2, 3], J[:, 2, 4] = -w * vx, -vy, -w * s
        J[:, 3, 1] = 1.0
        J[:, 4, 2], J[:, 4, 4] = vx, s
        J[:, 5, 2], J[:, 5, 3], J[:, 5, 4] = -w * vy, vx, w * c
        if model.vertical:
            xc[:, 6], xc[:, 7] = x[:, 5], x[:, 6]
            J[:, 6, 5] = J[:, 7, 6] = 1.0
        return xc, _sandwich(J, P)
    raise TypeError(f"no common-format conversion for {type(model).__name__}")


def to_cv_layout(model, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The CV-layout entries [x, vx, y, vy(, z, vz)] of :func:`to_common` (Sᵀ x_c and
    Sᵀ P_c S with the CV selector S), without the accelerations: for the track output
    (004 eq. 20-21), whose moments of these entries need only these entries. CT: the
    rows (x, v cosψ, y, v sinψ(, z, vz)) of the Jacobian of eq. 22."""
    if isinstance(model, ConstantVelocity):
        return x, 0.5 * (P + P.swapaxes(-1, -2))
    if isinstance(model, CoordinatedTurn):
        psi, v = x[:, 2], x[:, 4]
        c, s = np.cos(psi), np.sin(psi)
        vx, vy = v * c, v * s
        n, ndim = x.shape[0], model.ndim
        xo = np.empty((n, 2 * ndim))
        xo[:, 0], xo[:, 1], xo[:, 2], xo[:, 3] = x[:, 0], vx, x[:, 1], vy
        J = np.zeros((n, 2 * ndim, model.dim))
        J[:, 0, 0] = J[:, 2, 1] = 1.0
        J[:, 1, 2], J[:, 1, 4] = -vy, c
        J[:, 3, 2], J[:, 3, 4] = vx, s
        if model.vertical:
            xo[:, 4], xo[:, 5] = x[:, 5], x[:, 6]
            J[:, 4, 5] = J[:, 5, 6] = 1.0
        return xo, _sandwich(J, P)
    xc, Pc = to_common(model, x, P)
    idx = _cv_common_index(model.ndim)
    return xc[:, idx], Pc[:, idx[:, None], idx[None, :]]


def from_common(model, xc: np.ndarray, Pc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Common-format states/covariances → the model's native format (for re-initialising
    each mode filter after IMM mixing)."""
    if isinstance(model, (Singer, ConstantAcceleration)):
        return xc, Pc
    if isinstance(model, ConstantVelocity):
        # x S and Sᵀ P S select the CV entries (exact)
        idx = _cv_common_index(model.ndim)
        Pcv = Pc[:, idx[:, None], idx[None, :]]
        return xc[:, idx], 0.5 * (Pcv + Pcv.swapaxes(-1, -2))
    if isinstance(model, CoordinatedTurn):
        n = xc.shape[0]
        vx, ax, vy, ay = xc[:, 1], xc[:, 2], xc[:, 4], xc[:, 5]
        v2 = np.maximum(vx * vx + vy * vy, _MIN_SPEED**2)
        v = np.sqrt(v2)
        cross = vx * ay - vy * ax
        x = np.zeros((n, model.dim))
        x[:, 0], x[:, 1] = xc[:, 0], xc[:, 3]
        x[:, 2] = np.arctan2(vy, vx)
        x[:, 3] = cross / v2
        x[:, 4] = v
        J = np.zeros((n, model.dim, xc.shape[1]))
        J[:, 0, 0] = J[:, 1, 3] = 1.0
        J[:, 2, 1], J[:, 2, 4] = -vy / v2, vx / v2
        J[:, 3, 1] = ay / v2 - 2 * vx * cross / v2**2
        J[:, 3, 4] = -ax / v2 - 2 * vy * cross / v2**2
        J[:, 3, 2], J[:, 3, 5] = -vy / v2, vx / v2
        J[:, 4, 1], J[:, 4, 4] = vx / v, vy / v
        if model.vertical:
            x[:, 5], x[:, 6] = xc[:, 6], xc[:, 7]
            J[:, 5, 6] = J[:, 6, 7] = 1.0
        P = _sandwich(J, Pc)
        # When the speed is not significantly above its uncertainty (e.g. a one-point
        # initiation with zero velocity), course and turn rate are undefined and the
        # linearisation explodes: use an uninformative course (σ_ψ = π), the turn rate
        # implied by the acceleration spread, and no correlations for ψ, ω, v.
        var_v = 0.5 * (Pc[:, 1, 1] + Pc[:, 4, 4])
        weak = v2 < SPEED_SIGNIFICANCE**2 * var_v
        if weak.any():
            w = np.flatnonzero(weak)
            P[w, 2:5, :] = 0.0  # the polar entries ψ, ω, v
            P[w, :, 2:5] = 0.0
            P[w, 2, 2] = np.pi**2
            P[w, 3, 3] = 0.5 * (Pc[w, 2, 2] + Pc[w, 5, 5]) / np.maximum(var_v[w], 1.0)
            P[w, 4, 4] = v2[w] + var_v[w]
            x[w, 3] = 0.0
        return x, P
    raise TypeError(f"no common-format conversion for {type(model).__name__}")
