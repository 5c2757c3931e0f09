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


def test_live_service_fixes_the_frame_when_the_first_batch_is_applied():
    """Live: the sites heard before the first plot batch is applied all count, a site
    heard during that batch's reorder hold included (Zenoh delivers the site and plot
    keys on separate threads: a site published first can arrive after the first plots);
    a site heard after it does not move the frame."""
    import numpy as np
    from service_support import make_batch, make_site
    from skyfuse.services.fusion.pipeline import TrackPipeline
    from skyfuse.services.fusion.service import FusionConfig, FusionCore

    frames = []
    cfg = FusionConfig(reorder_wait=1.0, future_tolerance=None)
    core = FusionCore(cfg, lambda f: frames.append(f) or TrackPipeline(f))
    a, b, c = make_site("A", 44.0, 20.0), make_site("B", 46.0, 22.0), make_site("C", 45.0, 23.0)
    core.on_site(a)
    core.on_site(b)
    assert frames == [] and core.status().message == "waiting for plots"
    core.on_plots(make_batch("A", 0, 0, 4, 3, np.random.default_rng(1)), arrival=0.0)
    core.on_site(c)  # delivered after the first plots, within their hold
    assert frames == [] and core.poll(now=0.5) == []  # still held
    core.poll(now=1.0)
    assert frames == [frame_for_sites([a, b, c])]
    lat, lon = sites_centre([a, b, c])
    assert (frames[0].lat0, frames[0].lon0) == (lat, lon)
    assert 44.9 < lat < 45.1 and 21.5 < lon < 21.8  # not at site A, nor at A and B only
    core.on_site(make_site("D", 50.0, 30.0))
    core.on_plots(make_batch("D", 0, 0, 4, 3, np.random.default_rng(2)), arrival=1.5)
    core.poll(now=3.0)
    assert frames == [frame_for_sites([a, b, c])]
