"""ASTERIX adapter: CAT048/CAT034 plots and CAT010/CAT020/CAT021 reports in, CAT048/CAT034
and CAT062 out.

See ``docs/asterix.md``. Public API:

* :func:`read_asterix` (pcap or raw file → :class:`AsterixReadResult`: radar sector
  batches and the batches of report-based sensors, :mod:`.report_batches`),
  :func:`merge_results` (several recordings as one) and :class:`AsterixStreamDecoder`
  (UDP datagrams → PlotBatches as sectors and report cycles complete);
* :func:`read_reports` (pcap or raw file → CAT010 surface/MLAT, CAT020 WAM and CAT021
  ADS-B target reports; the stream decoder hands them out too);
* :func:`load_sites` (sites TOML → radar id ``"SAC-SIC"`` → RadarSite);
* :class:`AsterixPlotWriter` (PlotBatch → CAT048 + CAT034 data blocks);
* :class:`Cat062Writer` (TrackBatch → CAT062 data blocks), :func:`decode_cat062` and
  :func:`read_cat062` (CAT062 → :class:`Cat062Track`).
"""

from __future__ import annotations

from .cat062 import Cat062Track, decode_cat062, read_cat062
from .cat062_writer import Cat062Writer
from .pcap import build_pcap
from .reader import (
    AsterixReadResult,
    AsterixStreamDecoder,
    TimeOfDayResolver,
    altitude_to_flight_level,
    flight_level_to_altitude,
    merge_results,
    read_asterix,
)
from .scan_period import estimate_scan_period
from .sites import SitesError, load_sites, parse_sites, radar_id_for, sac_sic_of
from .surveillance import SurveillanceDecoder, read_reports
from .writer import AsterixPlotWriter

__all__ = [
    "AsterixPlotWriter",
    "AsterixReadResult",
    "AsterixStreamDecoder",
    "Cat062Track",
    "Cat062Writer",
    "SitesError",
    "SurveillanceDecoder",
    "TimeOfDayResolver",
    "altitude_to_flight_level",
    "build_pcap",
    "decode_cat062",
    "estimate_scan_period",
    "flight_level_to_altitude",
    "load_sites",
    "merge_results",
    "parse_sites",
    "radar_id_for",
    "read_asterix",
    "read_cat062",
    "read_reports",
    "sac_sic_of",
]
