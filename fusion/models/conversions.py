"""State conversions to and from the common (Singer-format) state of the three-model
IMM ([Dikić] eq. 22), with covariances by the Jacobian of each conversion.

Common format: [x, vx, ax, y, vy, ay(, z, vz, az)] (the Singer/CA layout).
* CV [x, vx, y, vy(, z, vz)] → common: accelerations a = 0 with zero variance; back:
  drop the accelerations ([Dikić]: "CV states get a_x = a_y = 0").
* CT (x, y, ψ, ω, v(, z, vz)) → common: v_x = v cosψ, v_y = v sinψ, a_x = −ω v_y,
  a_y = ω v_x ([Dikić] eq. 22); back: ψ = atan2(v_y, v_x), v = |v|, ω = (v_x a_y − v_y a_x)/v²
  (when |v| is within 3σ of zero, course and turn rate get an uninformative covariance).
  The vertical channel (z, vz) maps to (z, vz, az = 0). The CT conversions are compiled
  loops over the states (:mod:`fusion.models.coordinated_turn_kernels`).
* Singer/CA: identity.
"""

from __future__ import annotations

import numpy as np

from . import coordinated_turn_kernels as ct_kernels
from .ca import ConstantAcceleration
from .coordinated_turn import CoordinatedTurn
from .cv import ConstantVelocity
from .singer import Singer

_MIN_SPEED = 1e-3  # m/s, below it the course of a CT state is undefined
SPEED_SIGNIFICANCE = 3.0
"""CT course/turn rate are linearised only when |v| > 3 σ_v; below, uninformative."""


def _f64(a: np.ndarray) -> np.ndarray:
    """float64, C-contiguous (the one signature of the compiled conversions)."""
    return np.ascontiguousarray(a, dtype=np.float64)


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
        return ct_kernels.to_common(_f64(x), _f64(P), model.vertical)
    raise TypeError(f"no common-format conversion for {type(model).__name__}")


def to_cv_layout(model, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The CV-layout entries [x, vx, y, vy(, z, vz)] of :func:`to_common` (Sᵀ x_c and
    Sᵀ P_c S with the CV selector S), without the accelerations: for the track output
    ([Dikić] eq. 20-21), whose moments of these entries need only these entries. CT: the
    rows (x, v cosψ, y, v sinψ(, z, vz)) of the Jacobian of eq. 22."""
    if isinstance(model, ConstantVelocity):
        return x, 0.5 * (P + P.swapaxes(-1, -2))
    if isinstance(model, CoordinatedTurn):
        return ct_kernels.to_cv_layout(_f64(x), _f64(P), model.vertical)
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
        # When the speed is not significantly above its uncertainty (e.g. a one-point
        # initiation with zero velocity), course and turn rate are undefined and the
        # linearisation explodes: the kernel gives an uninformative course (σ_ψ = π),
        # the turn rate implied by the acceleration spread, and no correlations for
        # ψ, ω, v.
        return ct_kernels.from_common(
            _f64(xc), _f64(Pc), model.vertical, _MIN_SPEED, SPEED_SIGNIFICANCE
        )
    raise TypeError(f"no common-format conversion for {type(model).__name__}")
