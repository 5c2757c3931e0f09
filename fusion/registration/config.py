"""Online sensor registration settings (docs/concepts/registration.md), loadable from TOML.

Units: azimuth rad (flags in degrees where a name says ``_deg``), range m, range gain
dimensionless (ppm where a name says ``_ppm``), time s.
"""

from __future__ import annotations

import math
from enum import StrEnum

import numpy as np
from pydantic import BaseModel, Field, field_validator
from skyfuse.fusion.frames.sensor_bias import BIAS_COMPONENTS


class RegistrationMode(StrEnum):
    """``on``: estimate and correct; ``frozen``: correct with the current estimate, no
    more updates; ``off``: no estimation and no correction."""

    ON = "on"
    FROZEN = "frozen"
    OFF = "off"


class RegistrationConfig(BaseModel):
    """Online registration settings (defaults: on, all four components, static biases)."""

    mode: RegistrationMode = Field(RegistrationMode.ON, description="on, frozen or off")
    reference: list[str] = Field(
        default_factory=list,
        description="Reference sensors (bias fixed at 0): radars, or report sensors such as "
        "an ADS-B (their positions taken as unbiased, the radars all estimated); empty: the "
        "first radar seen",
    )
    max_reference_sigma: float | None = Field(
        None,
        gt=0,
        description="Reports of reference report sensors (ADS-B, multilateration) whose "
        "horizontal σ per axis exceeds this are not used (poor quality: e.g. 40 m keeps ADS-B "
        "NACp ≥ 8), m; null: all",
    )
    components: list[str] = Field(
        default_factory=lambda: list(BIAS_COMPONENTS),
        description="Bias components estimated: azimuth, range, range_gain, time",
    )
    prior_azimuth_deg: float = Field(0.5, gt=0, description="Prior σ of the azimuth bias, deg")
    prior_range_m: float = Field(300.0, gt=0, description="Prior σ of the range offset, m")
    prior_range_gain_ppm: float = Field(500.0, gt=0, description="Prior σ of the range gain, ppm")
    prior_time_s: float = Field(0.25, gt=0, description="Prior σ of the time offset, s")
    drift_per_hour: float = Field(
        0.0,
        ge=0,
        description="Random-walk drift: fraction of the prior σ the biases may wander per hour",
    )
    max_pair_dt: float = Field(
        8.0, gt=0, le=60, description="Longest time between two radars' plots of a pair, s"
    )
    min_ground_range: float = Field(
        10_000.0, ge=0, description="Plots nearer a radar than this (m) are not used"
    )
    q: float = Field(25.0, ge=0, description="Target acceleration variance, m²/s⁴ (pairing)")
    p_gate: float = Field(0.999, gt=0.5, lt=1.0, description="Residual gate probability")
    confirmed_only: bool = Field(True, description="Use only confirmed tracks")
    apply_sigma: float = Field(
        3.0,
        ge=0,
        description="Correct a component only once its estimate exceeds this many σ of its "
        "own uncertainty (0: correct by every estimate); an unbiased radar is left alone",
    )
    capacity: int = Field(20_000, ge=16, description="Bound on stored plots awaiting a pair")

    @field_validator("components")
    @classmethod
    def _known(cls, v: list[str]) -> list[str]:
        bad = sorted(set(v) - set(BIAS_COMPONENTS))
        if bad:
            raise ValueError(f"component {bad[0]!r}: must be one of {', '.join(BIAS_COMPONENTS)}")
        if not v:
            raise ValueError("components: at least one is needed")
        return v

    def prior_sigma(self) -> np.ndarray:
        """Prior standard deviations (rad, m, 1, s) in the bias vector order."""
        return np.array(
            [
                math.radians(self.prior_azimuth_deg),
                self.prior_range_m,
                self.prior_range_gain_ppm * 1e-6,
                self.prior_time_s,
            ]
        )

    def estimated_mask(self) -> np.ndarray:
        """(4,) bool: which components of (b_ψ, b_D, g, b_t) are estimated."""
        return np.array([c in self.components for c in BIAS_COMPONENTS])
