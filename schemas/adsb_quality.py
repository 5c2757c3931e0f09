"""ADS-B quality indicators → standard deviations (m, m/s).

ADS-B reports carry categories, not variances. Each category is an upper bound on a
95 % error:

* **NUCp** (RTCA DO-260, "version 0" transponders; CAT021 edition 0.23 I021/090 PA,
  CAT021 2.x I021/090 NUCp/NIC when the MOPS version I021/210 VN = 0): the horizontal
  protection limit HPL and the 95 % containment radius μ;
* **NACp** (RTCA DO-260A and DO-260B; CAT021 2.x I021/090 second extent): the
  estimated position uncertainty EPU, a 95 % bound on the horizontal position error;
* **NUCr** (DO-260) and **NACv** (DO-260A/B): a 95 % bound on the horizontal velocity
  error (CAT021 0.23 I021/095, 2.x I021/090 NUCr/NACv).

The same tables are reproduced in ICAO Doc 9871 (Technical Provisions for Mode S
Services and Extended Squitter). In the tables below a bound given in NM by the
standard is written as NM × 1852.

From a 95 % radius to σ: with a circular Gaussian error of standard deviation σ per
horizontal axis, the radial error r is Rayleigh distributed, P(r ≤ R) = 1 − exp(−R² /
2σ²), so R₉₅ = σ √(−2 ln 0.05) ≈ 2.4477 σ and

    σ = R₉₅ / 2.4477.

The categories are upper bounds (the error is *below* R₉₅ with 95 % probability), so
this σ is the largest the category allows: conservative. Category 0 ("unknown or
≥ 10 NM") gives ``None``.
"""

from __future__ import annotations

import math

NM = 1852.0
#: √(−2 ln 0.05): the 95 % quantile of the Rayleigh distribution in units of σ.
RAYLEIGH_95 = math.sqrt(-2.0 * math.log(0.05))

#: NUCp → horizontal protection limit HPL (m), RTCA DO-260.
NUCP_HPL_M = {
    9: 7.5,
    8: 25.0,
    7: 0.1 * NM,
    6: 0.2 * NM,
    5: 0.5 * NM,
    4: 1.0 * NM,
    3: 2.0 * NM,
    2: 10.0 * NM,
    1: 20.0 * NM,
}
#: NUCp → 95 % horizontal containment radius μ (m), RTCA DO-260.
NUCP_R95_M = {
    9: 3.0,
    8: 10.0,
    7: 0.05 * NM,
    6: 0.1 * NM,
    5: 0.25 * NM,
    4: 0.5 * NM,
    3: 1.0 * NM,
    2: 5.0 * NM,
    1: 10.0 * NM,
}
#: NACp → estimated position uncertainty EPU, 95 % horizontal bound (m), DO-260A/B.
NACP_EPU_M = {
    11: 3.0,
    10: 10.0,
    9: 30.0,
    8: 0.05 * NM,
    7: 0.1 * NM,
    6: 0.3 * NM,
    5: 0.5 * NM,
    4: 1.0 * NM,
    3: 2.0 * NM,
    2: 4.0 * NM,
    1: 10.0 * NM,
}
#: NUCr (DO-260) and NACv (DO-260A/B) → 95 % horizontal velocity error bound (m/s).
NACV_R95_MS = {4: 0.3, 3: 1.0, 2: 3.0, 1: 10.0}


def sigma_from_r95(r95: float) -> float:
    """Per-axis σ of a circular Gaussian whose 95 % radius is ``r95``."""
    return r95 / RAYLEIGH_95


def position_sigma_nucp(nucp: int | None) -> float | None:
    """Horizontal σ per axis (m) of a NUCp category, or ``None`` (0 or unknown)."""
    r95 = NUCP_R95_M.get(nucp) if nucp is not None else None
    return None if r95 is None else sigma_from_r95(r95)


def position_sigma_nacp(nacp: int | None) -> float | None:
    """Horizontal σ per axis (m) of a NACp category, or ``None`` (0 or 12-15)."""
    epu = NACP_EPU_M.get(nacp) if nacp is not None else None
    return None if epu is None else sigma_from_r95(epu)


def velocity_sigma(nac_v: int | None) -> float | None:
    """Horizontal velocity σ per axis (m/s) of a NUCr/NACv category, or ``None``."""
    r95 = NACV_R95_MS.get(nac_v) if nac_v is not None else None
    return None if r95 is None else sigma_from_r95(r95)
