"""Motion models. Each gives the transition ``F(dt)`` and process covariance ``Q(dt)``,
for a scalar ``dt`` (shape (d, d)) or an array of ``dt`` (shape (n, d, d)) so that many
tracks with different last-update times are predicted in one call. The nonlinear
coordinated-turn model gives ``transition(x, dt) -> (x_pred, jacobian)`` and ``Q(dt, x)``.

Linear models interleave the state per axis (CV ``[x, vx, y, vy(, z, vz)]``, CA and
Singer ``[x, vx, ax, y, vy, ay(, z, vz, az)]``), metres and seconds, x east, y north,
z up (the tracker convention of :mod:`fusion.frames`)."""

from .base import MotionModel
from .ca import ConstantAcceleration
from .conversions import from_common, to_common
from .coordinated_turn import CoordinatedTurn
from .cv import ConstantVelocity
from .singer import Singer, singer_sigma_m2

__all__ = [
    "ConstantAcceleration",
    "ConstantVelocity",
    "CoordinatedTurn",
    "MotionModel",
    "Singer",
    "from_common",
    "singer_sigma_m2",
    "to_common",
]
