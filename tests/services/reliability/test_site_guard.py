"""A site message that moves a known radar beyond ``site_tolerance`` is held and reported,
never applied silently; small corrections are applied (issue 14, part 4)."""

from __future__ import annotations

import pyproj
import pytest
from skyfuse.schemas import RadarKind, RadarSite, keys
from skyfuse.services.fusion.service import FusionConfig, FusionCore, site_displacement_m


def site(lat: float, lon: float = 20.0, alt: float = 100.0, **kw) -> RadarSite:
    return RadarSite(radar_id="R1", lat=lat, lon=lon, alt=alt, kind=RadarKind.TWO_D, **kw)


def test_displacement_matches_the_geodesic_distance():
    geod = pyproj.Geod(ellps="WGS84")
    a, b = site(45.0), site(45.5, 20.1)
    _, _, dist = geod.inv(a.lon, a.lat, b.lon, b.lat)
    # chord vs geodesic on ~56 km: differ by < 1 m (s³/24R²)
    assert site_displacement_m(a, b) == pytest.approx(dist, abs=1.0)
    assert site_displacement_m(a, site(45.0, alt=130.0)) == pytest.approx(30.0, abs=1e-6)


def test_a_moved_site_is_held_and_reported_a_small_correction_applied():
    core = FusionCore(
        FusionConfig(site_tolerance=100.0, frame_lat0=45.0, frame_lon0=20.0),
        pipeline_factory=lambda frame: object(),
    )
    key = keys.radar_site("R1")
    core.on_site_payload(key, site(45.0).to_json_bytes())
    core.on_site_payload(key, site(45.5).to_json_bytes())  # 55 km north
    r = core.radars["R1"]
    assert r.site == site(45.0)
    assert core.rejected["site change held"] == 1
    st = core.status()
    assert st.radars[0].site_held and "R1" in st.message
    # a 60 m re-survey of the antenna height is applied and clears the hold
    core.on_site_payload(key, site(45.0, alt=160.0).to_json_bytes())
    assert r.site == site(45.0, alt=160.0) and r.site_held is None
    assert not core.status().radars[0].site_held
    # accuracy changes without a move are applied
    core.on_site_payload(key, site(45.0, alt=160.0, sigma_range=80.0).to_json_bytes())
    assert r.site.sigma_range == 80.0 and core.rejected["site change held"] == 1
    # with the check off every change is applied
    core.cfg = FusionConfig(site_tolerance="off", frame_lat0=45.0, frame_lon0=20.0)
    assert core.cfg.site_tolerance is None
    assert FusionConfig(future_tolerance="OFF").future_tolerance is None
    core.on_site_payload(key, site(45.5).to_json_bytes())
    assert r.site == site(45.5)
