"""Filters batched over many tracks/components: states ``(n, d)``, covariances ``(n, d, d)``.

* :mod:`.kalman` — linear KF primitives (Joseph form);
* :mod:`.ekf` — predict/update for nonlinear models and measurements;
* :mod:`.model_filter` — :func:`ConvertedMeasurementKF`, :func:`PolarEKF`, initiation;
* :mod:`.imm_interaction` — the IMM interaction (mixing) step, [Dikić] eq. 15-17, of the
  IMM track density (:mod:`fusion.tracker.density.imm_mixture`, which is the IMM of
  skyfuse: one IMM per track with ``depth = 0``).
"""

from .gaussian_state import GaussianState
from .measurement_models import PolarMeasurement, PositionMeasurement, wrap_angle
from .model_filter import ConvertedMeasurementKF, ModelFilter, PolarEKF

__all__ = [
    "ConvertedMeasurementKF",
    "GaussianState",
    "ModelFilter",
    "PolarEKF",
    "PolarMeasurement",
    "PositionMeasurement",
    "wrap_angle",
]
