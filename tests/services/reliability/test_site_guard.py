"""A site message that moves a known radar beyond ``site_tolerance`` is held and reported,
never applied silently; small corrections are applied (docs/reliability.md §4)."""

from __future__ import annotations

import pymap3d
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


def _north(base: RadarSite, metres: float) -> RadarSite:
    lat, lon, _ = pymap3d.enu2geodetic(0.0, metres, 0.0, base.lat, base.lon, base.alt)
    return base.model_copy(update={"lat": float(lat), "lon": float(lon)})


def test_small_steps_do_not_add_up_and_the_genuine_site_is_never_held():
    """40 site messages each 90 m from the previous one (under the 100 m tolerance) moved
    the radar 3.6 km without a warning, after which the genuine site was the one held.
    Moves are measured from the accepted site: at most one step is applied (90 m, a
    re-survey), the rest held and reported, and the genuine site is applied again."""
    core = FusionCore(
        FusionConfig(site_tolerance=100.0, frame_lat0=45.0, frame_lon0=20.0),
        pipeline_factory=lambda frame: object(),
    )
    key, genuine = keys.radar_site("R1"), site(45.0)
    core.on_site_payload(key, genuine.to_json_bytes())
    r, s = core.radars["R1"], genuine
    for _ in range(40):
        s = _north(s, 90.0)
        core.on_site_payload(key, s.to_json_bytes())
        assert site_displacement_m(genuine, r.site) <= 100.0
    assert site_displacement_m(genuine, s) == pytest.approx(3600.0, rel=1e-3)
    assert core.rejected["site change held"] == 39
    assert core.status().radars[0].site_held and "accept_sites" in core.status().message
    core.on_site_payload(key, genuine.to_json_bytes())  # the sensor's own site again
    assert r.site == genuine and r.site_held is None


def test_the_operator_accepts_a_move_and_later_moves_are_held_again():
    cfg = FusionConfig(site_tolerance=100.0, frame_lat0=45.0, frame_lon0=20.0)
    key, old = keys.radar_site("R1"), site(45.0)
    moved = _north(old, 2000.0)
    core = FusionCore(cfg, pipeline_factory=lambda frame: object())
    core.on_site(old, configured=True)  # e.g. the saved state of the previous run
    core.on_site_payload(key, moved.to_json_bytes())
    assert core.radars["R1"].site == old and core.radars["R1"].site_held == moved
    accepting = FusionCore(
        cfg.model_copy(update={"accept_sites": ["R1"]}), pipeline_factory=lambda frame: object()
    )
    accepting.on_site(old, configured=True)
    accepting.on_site_payload(key, moved.to_json_bytes())  # accepted: the new reference
    r = accepting.radars["R1"]
    assert r.site == moved and r.site_held is None and r.site_accepted == moved
    accepting.on_site_payload(key, _north(moved, 500.0).to_json_bytes())
    assert r.site == moved and r.site_held is not None  # once only
    # a configured site is the accepted one: a saved site never replaces it
    configured = FusionCore(
        cfg.model_copy(update={"sites": [moved]}), pipeline_factory=lambda frame: object()
    )
    configured.on_site(old, configured=True)
    assert configured.radars["R1"].site == moved
