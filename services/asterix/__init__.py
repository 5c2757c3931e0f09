"""ASTERIX adapter: CAT048/CAT034 plots in, CAT048/CAT034 and CAT062 out.

See ``docs/asterix.md``. Public API:

* :func:`read_asterix` (pcap or raw file → :class:`AsterixReadResult`) and
  :class:`AsterixStreamDecoder` (UDP datagrams → PlotBatches as sectors complete);
* :func:`load_sites` (sites TOML → radar id ``"SAC-SIC"`` → RadarSite);
* :class:`AsterixPlotWriter` (PlotBatch → CAT048 + CAT034 data blocks);
* :class:`Cat062Writer` (Track / TrackBatch → CAT062) and :func:`decode_cat062`.
"""

from __future__ import annotations

from .reader import (
    AsterixReadResult,
    AsterixStreamDecoder,
    TimeOfDayResolver,
    altitude_to_flight_level,
    flight_level_to_altitude,
    read_asterix,
)
from .scan_period import estimate_scan_period
from .sites import SitesError, load_sites, parse_sites, radar_id_for, sac_sic_of

__all__ = [
    "AsterixReadResult",
    "AsterixStreamDecoder",
    "SitesError",
    "TimeOfDayResolver",
    "altitude_to_flight_level",
    "estimate_scan_period",
    "flight_level_to_altitude",
    "load_sites",
    "parse_sites",
    "radar_id_for",
    "read_asterix",
    "sac_sic_of",
]
