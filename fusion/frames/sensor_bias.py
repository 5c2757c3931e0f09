"""Systematic (registration) errors of one polar radar and their correction.

The bias model is the standard one of radar registration (Fischer, Muehe & Cameron,
"Registration errors in a netted air surveillance system", MIT Lincoln Laboratory
TN 1980-40; Okello & Ristic, IEEE TAES 39(3), 2003, §II; the ARTAS sensor-bias
vector): a radar reports, for a target at true slant range D, azimuth ψ and time t,

    D_m = (1 + g) D + b_D,    ψ_m = ψ + b_ψ,    t_m = t + b_t                    (1)

with range gain error g (dimensionless), range offset b_D (m), azimuth offset b_ψ (rad,
clockwise from north) and time-stamping offset b_t (s). Random noise comes on top and is
not part of the bias. The simulator applies (1) with :meth:`SensorBias.distort`; the plot
conversion inverts it with :meth:`SensorBias.correct`:

    D = (D_m − b_D)/(1 + g),   ψ = ψ_m − b_ψ,   t = t_m − b_t                    (2)

The vector order used by the registration estimator is ``(b_ψ, b_D, g, b_t)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

BIAS_COMPONENTS = ("azimuth", "range", "range_gain", "time")
"""Order of the bias vector: azimuth rad, range m, range gain (1), time s."""
BIAS_UNITS = ("rad", "m", "1", "s")


@dataclass(frozen=True)
class SensorBias:
    """Systematic errors of one radar (eq. 1): ``azimuth`` rad, ``range`` m,
    ``range_gain`` dimensionless (measured = (1 + gain) × true + offset), ``time`` s
    (reported time = true time + offset)."""

    azimuth: float = 0.0
    range: float = 0.0
    range_gain: float = 0.0
    time: float = 0.0

    def __post_init__(self) -> None:
        for name in BIAS_COMPONENTS:
            v = getattr(self, name)
            if not math.isfinite(v):
                raise ValueError(f"bias {name} = {v}: must be finite")
        if not -0.5 < self.range_gain < 0.5:
            raise ValueError(f"bias range_gain = {self.range_gain}: must be in (-0.5, 0.5)")

    @classmethod
    def from_vector(cls, v) -> SensorBias:
        """From ``(b_ψ rad, b_D m, g, b_t s)``."""
        a = np.asarray(v, float).reshape(4)
        return cls(float(a[0]), float(a[1]), float(a[2]), float(a[3]))

    def vector(self) -> np.ndarray:
        """``(b_ψ rad, b_D m, g, b_t s)``, shape (4,)."""
        return np.array([self.azimuth, self.range, self.range_gain, self.time])

    @property
    def is_zero(self) -> bool:
        return not any(self.vector())

    @property
    def time_ns(self) -> int:
        """The time offset in integer ns."""
        return round(self.time * 1e9)

    def distort(self, D, psi, t_ns):
        """True (D m, ψ rad, t ns) → what the biased radar reports (eq. 1); ψ wrapped
        into [0, 2π)."""
        D = (1.0 + self.range_gain) * np.asarray(D, float) + self.range
        psi = np.mod(np.asarray(psi, float) + self.azimuth, 2 * math.pi)
        return D, psi, np.asarray(t_ns, np.int64) + self.time_ns

    def correct(self, D, psi, t_ns):
        """Reported (D m, ψ rad, t ns) → bias-corrected values (eq. 2); ψ wrapped
        into [0, 2π)."""
        D = (np.asarray(D, float) - self.range) / (1.0 + self.range_gain)
        psi = np.mod(np.asarray(psi, float) - self.azimuth, 2 * math.pi)
        return D, psi, np.asarray(t_ns, np.int64) - self.time_ns
