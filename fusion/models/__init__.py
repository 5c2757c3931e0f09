"""Motion models. Each gives the transition ``F(dt)`` and process covariance ``Q(dt)``,
for a scalar ``dt`` (shape (d, d)) or an array of ``dt`` (shape (n, d, d)) so that many
tracks with different last-update times are predicted in one call."""

from .base import MotionModel
from .cv import ConstantVelocity

__all__ = ["ConstantVelocity", "MotionModel"]
