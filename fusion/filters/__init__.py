"""Filters batched over many tracks/components: states ``(n, d)``, covariances ``(n, d, d)``.

* :mod:`.kalman` — linear KF primitives (Joseph form);
* :mod:`.ekf` — predict/update for nonlinear models and measurements;
* :mod:`.model_filter` — :func:`ConvertedMeasurementKF`, :func:`PolarEKF`, initiation;
* :mod:`.imm` — :class:`IMM`, :func:`imm2_pcwpa`, :func:`imm3_cv_singer_ct` (spec 01 §5);
* :mod:`.imm_interaction` — the IMM interaction (mixing) step, [Dikić] eq. 15-17.
"""

from .gaussian_state import GaussianState
from .imm import IMM, SOURCE_TPM_IMM2, TYPICAL_TPM_IMM2, IMMState, imm2_pcwpa, imm3_cv_singer_ct
from .measurement_models import PolarMeasurement, PositionMeasurement, wrap_angle
from .model_filter import ConvertedMeasurementKF, ModelFilter, PolarEKF

__all__ = [
    "IMM",
    "SOURCE_TPM_IMM2",
    "TYPICAL_TPM_IMM2",
    "ConvertedMeasurementKF",
    "GaussianState",
    "IMMState",
    "ModelFilter",
    "PolarEKF",
    "PolarMeasurement",
    "PositionMeasurement",
    "imm2_pcwpa",
    "imm3_cv_singer_ct",
    "wrap_angle",
]
