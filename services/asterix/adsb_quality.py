"""ADS-B quality indicators → standard deviations: the tables and conversions live in
:mod:`skyfuse.schemas.adsb_quality` (the scenario simulator draws its ADS-B errors from
them too); this name is kept for the ASTERIX readers."""

from skyfuse.schemas.adsb_quality import (  # noqa: F401
    NACP_EPU_M,
    NACV_R95_MS,
    NM,
    NUCP_HPL_M,
    NUCP_R95_M,
    RAYLEIGH_95,
    position_sigma_nacp,
    position_sigma_nucp,
    sigma_from_r95,
    velocity_sigma,
)
