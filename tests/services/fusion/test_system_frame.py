"""The one frame rule (live and offline): spherical mean of the sites, against closed forms
and pyproj's geodesic midpoint."""

from __future__ import annotations

import pytest
from pyproj import Geod
from skyfuse.schemas import FrameKind, RadarKind, RadarSite
from skyfuse.services.fusion.system_frame import frame_for_sites, sites_centre


def site(rid: str, lat: float, lon: float) -> RadarSite:
    return RadarSite(
        radar_id=rid, lat=lat, lon=lon, alt=100.0, kind=RadarKind.TWO_D, scan_period=4.0,
        n_sectors=4, sigma_range=50.0, sigma_azimuth=0.002,
    )  # fmt: skip


def test_two_sites_on_the_equator_centre_between_them():
    assert sites_centre([site("a", 0.0, 10.0), site("b", 0.0, 20.0)]) == pytest.approx((0, 15))


def test_antimeridian_sites_centre_on_the_antimeridian_not_greenwich():
    lat, lon = sites_centre([site("a", 10.0, 179.0), site("b", 10.0, -179.0)])
    assert abs(abs(lon) - 180.0) < 1e-9 and lat == pytest.approx(10.0, abs=0.01)


def test_two_sites_centre_is_the_great_circle_midpoint():
    a, b = site("a", 44.8, 20.3), site("b", 42.4, 19.2)
    lon_m, lat_m = Geod(ellps="sphere").npts(a.lon, a.lat, b.lon, b.lat, 1)[0]
    lat, lon = sites_centre([b, a])  # order-free
    assert (lat, lon) == pytest.approx((lat_m, lon_m), abs=1e-9)


def test_configured_origin_wins_and_no_site_gives_none():
    spec = frame_for_sites([site("a", 1, 2)], "ned", lat0=45.0, lon0=20.0, alt0=5.0)
    assert (spec.kind, spec.lat0, spec.lon0, spec.alt0) == (FrameKind.NED, 45.0, 20.0, 5.0)
    assert frame_for_sites([]) is None
    one = frame_for_sites([site("a", 44.0, 21.0)])
    assert (one.kind, one.lat0, one.lon0, one.alt0) == (FrameKind.STEREOGRAPHIC, 44.0, 21.0, 0.0)


def test_live_service_fixes_the_frame_at_the_first_plot_from_all_sites_known():
    """Live: sites heard before the first plot batch all count (not only the first one);
    a site heard later does not move the frame."""
    import numpy as np
    from service_support import make_batch, make_site
    from skyfuse.services.fusion.service import FusionConfig, FusionCore

    frames = []
    core = FusionCore(FusionConfig(reorder_wait=0.0), lambda f: frames.append(f) or f)
    a, b = make_site("A", 44.0, 20.0), make_site("B", 46.0, 22.0)
    core.on_site(a)
    core.on_site(b)
    assert frames == [] and core.status().message == "waiting for plots"
    core.on_plots(make_batch("A", 0, 0, 4, 3, np.random.default_rng(1)), arrival=0.0)
    core.on_site(make_site("C", 50.0, 30.0))
    assert frames == [frame_for_sites([a, b])]
    lat, lon = sites_centre([a, b])
    assert (frames[0].lat0, frames[0].lon0) == (lat, lon)
    assert 44.9 < lat < 45.1 and 20.9 < lon < 21.1  # near the midpoint, not at site A
