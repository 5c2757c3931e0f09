"""The report sensors a scenario may add beside its radars (scenario parameters, e.g.
``skyfuse simulate --param adsb=true,adsb_poor_fraction=0.1``):

* ``adsb``: an ADS-B ground network ``ADSB`` (``wgs84``, reports every ``adsb_period``
  s, range 250 km from the scenario centre) reporting a share ``adsb_equipped_fraction``
  of the Mode-S aircraft with NACp ``adsb_nacp`` (``adsb_poor_fraction`` of them
  ``adsb_poor_nacp``) and velocities of NACv ``adsb_nac_v``;
* ``mlat``: a wide-area multilateration ``MLAT`` (``cartesian`` east/north of its
  reference point, the first radar's airport) reporting every transponder inside a
  regular octagon of circumradius ``mlat_radius`` m, σ = √(``mlat_sigma``² +
  (``mlat_sigma_growth`` ρ)²) per axis at ρ m from the reference point.

Both are report sensors (``detection = reports``, ``timing = plots``, one batch per
cycle, no sectors; their model: :mod:`fusion.sim.reports`). Off by default, so a
scenario's radars and their plots are those of its radars alone.
"""

from __future__ import annotations

import math

import numpy as np
import pymap3d
from skyfuse.schemas import RadarSite
from skyfuse.schemas.adsb_quality import position_sigma_nacp

from .scenario import Param, in_range, positive, probability
from .sensor import ReportModel, SensorConfig


def _nacp(v) -> str | None:
    return None if position_sigma_nacp(v) is not None else "must be a NACp category in 1..11"


REPORT_PARAMETERS = {
    "adsb": Param(False, "add an ADS-B ground network ADSB (report sensor, wgs84)"),
    "adsb_period": Param(1.0, "ADS-B report cycle, s", positive),
    "adsb_p_detection": Param(
        0.95, "probability that an equipped aircraft is reported in a cycle", probability
    ),
    "adsb_equipped_fraction": Param(
        0.8,
        "share of the Mode-S aircraft with ADS-B out (the others are never reported)",
        in_range(0, 1),
    ),
    "adsb_nacp": Param(9, "NACp of the equipped aircraft (9: EPU 30 m, σ 12.3 m per axis)", _nacp),
    "adsb_poor_fraction": Param(
        0.0, "share of the equipped aircraft whose positions have adsb_poor_nacp", in_range(0, 1)
    ),
    "adsb_poor_nacp": Param(6, "NACp of the poor ones (6: EPU 0.3 NM, σ 227 m)", _nacp),
    "adsb_nac_v": Param(2, "NACv of the reported velocities (0: none)", in_range(0, 4)),
    "mlat": Param(False, "add a wide-area multilateration MLAT (report sensor, cartesian)"),
    "mlat_period": Param(1.0, "multilateration update cycle, s", positive),
    "mlat_p_detection": Param(
        0.9, "probability that a transponder is located in a cycle", probability
    ),
    "mlat_radius": Param(40_000.0, "circumradius of the octagonal coverage, m", positive),
    "mlat_sigma": Param(5.0, "σ per axis at the reference point, m", positive),
    "mlat_sigma_growth": Param(2.5e-3, "growth of σ with the distance, m per m", in_range(0, 1)),
}
"""The report sensors' scenario parameters (module docstring)."""


def _octagon(lat: float, lon: float, alt: float, radius: float) -> list[tuple[float, float]]:
    """WGS-84 vertices of a regular octagon of circumradius ``radius`` m about a point."""
    a = np.arange(8) * (math.pi / 4)
    la, lo, _ = pymap3d.enu2geodetic(radius * np.sin(a), radius * np.cos(a), 0.0, lat, lon, alt)
    return [(float(x), float(y)) for x, y in zip(np.asarray(la), np.asarray(lo), strict=True)]


def report_sensors(p: dict, centre: tuple[float, float], airport: tuple) -> list[SensorConfig]:
    """The ADS-B network (at ``centre`` lat/lon) and the multilateration (reference point
    ``airport`` lat/lon/alt) the parameter values ``p`` ask for."""
    out = []
    common = dict(detection="reports", timing="plots", clutter_density=0.0, n_sectors=1,
                  sigma_altitude=15.0)  # fmt: skip
    if p["adsb"]:
        site = RadarSite(
            radar_id="ADSB", name="ADS-B ground network", lat=centre[0], lon=centre[1],
            kind="wgs84", sigma_cartesian=position_sigma_nacp(p["adsb_nacp"]),
            scan_period=p["adsb_period"], report_timeout=5 * p["adsb_period"],
            p_detection=p["adsb_p_detection"], max_range=250_000.0, **common,
        )  # fmt: skip
        model = ReportModel(p["adsb_equipped_fraction"], p["adsb_nacp"], p["adsb_poor_fraction"],
                            p["adsb_poor_nacp"], p["adsb_nac_v"])  # fmt: skip
        out.append(SensorConfig(site=site, report=model))
    if p["mlat"]:
        radius = p["mlat_radius"]
        site = RadarSite(
            radar_id="MLAT", name="wide-area multilateration", lat=airport[0], lon=airport[1],
            alt=airport[2], kind="cartesian", sigma_cartesian=p["mlat_sigma"],
            sigma_growth=p["mlat_sigma_growth"], scan_period=p["mlat_period"],
            report_timeout=5 * p["mlat_period"], p_detection=p["mlat_p_detection"],
            max_range=radius + 20_000.0, coverage=_octagon(*airport, radius), **common,
        )  # fmt: skip
        out.append(SensorConfig(site=site))
    return out
