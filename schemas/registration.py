"""``RegistrationStatus``: a fusion service's online sensor-registration estimates, on
``skyfuse/@v1/fusion/{id}/registration`` and in ``Status.registration``.

Each radar's systematic errors (azimuth offset rad clockwise, range offset m, range gain
dimensionless, time-stamping offset s; reported = (1 + gain) × true + offset, time + offset)
with their standard deviations; reference radars are fixed at 0 (σ 0).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from .base import WireModel
from .keys import ID_PATTERN


class RadarBiasEstimate(WireModel):
    """One radar's estimated biases and their 1σ uncertainties (SI units)."""

    radar_id: str = Field(pattern=ID_PATTERN)
    reference: bool = Field(description="A reference radar (bias fixed at 0)")
    azimuth: float = Field(description="Azimuth offset, rad clockwise")
    azimuth_sigma: float = Field(ge=0.0, description="σ of the azimuth offset, rad")
    range: float = Field(description="Range offset, m")
    range_sigma: float = Field(ge=0.0, description="σ of the range offset, m")
    range_gain: float = Field(description="Range gain error, 1")
    range_gain_sigma: float = Field(ge=0.0, description="σ of the range gain error, 1")
    time: float = Field(description="Time-stamping offset, s")
    time_sigma: float = Field(ge=0.0, description="σ of the time offset, s")
    pairs_used: int = Field(0, ge=0, description="Common-target pairs that updated it")
    pairs_rejected: int = Field(0, ge=0, description="Pairs refused by the residual gate")


class RegistrationStatus(WireModel):
    """The registration of one fusion service at ``time`` (tracker time, ns UTC)."""

    fusion_id: str = Field(pattern=ID_PATTERN)
    time: int = Field(ge=0, description="Time of the last plot batch applied, ns UTC")
    mode: Literal["on", "frozen", "off"] = Field(description="on, frozen or off")
    radars: list[RadarBiasEstimate] = Field(default_factory=list)
    plots_waiting: int = Field(0, ge=0, description="Plots stored awaiting a partner")
    plots_dropped: int = Field(0, ge=0, description="Plots dropped from the bounded store")
    plots_not_finite: int = Field(0, ge=0, description="Rows skipped: non-finite values")
