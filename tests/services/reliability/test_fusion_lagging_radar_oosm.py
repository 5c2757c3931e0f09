"""``skyfuse fusion`` as a process on loopback with two radars seeing the same aircraft:
R1 on time, R2 with its clock 1 s behind (within max_lateness 2 s), R3 3.5 s behind
(beyond it). Expected: R2's batches are released late and their plots update the track
through the out-of-sequence update (counted in ``Status.late``: OOSM batches, plots,
track updates, hits), R3's are refused as too late and counted, and the feed's time never
goes backwards although late cycles are published."""

from __future__ import annotations

import time

import numpy as np
import pymap3d
import pytest
from skyfuse.schemas import PlotBatch, RadarKind, RadarSite, Status, TrackBatch, keys
from skyfuse.services.runtime.transport import (
    Inbox,
    TransportConfig,
    declare_publisher,
    free_port,
    open_session,
    service_alive_key,
    wait_for_tokens,
    wall_stamp,
)

pytestmark = pytest.mark.service
S = 1_000_000_000
SITES = {
    "R1": RadarSite(radar_id="R1", lat=45.0, lon=20.0, alt=100.0, kind=RadarKind.TWO_D),
    "R2": RadarSite(radar_id="R2", lat=45.2, lon=20.1, alt=100.0, kind=RadarKind.TWO_D),
    "R3": RadarSite(radar_id="R3", lat=45.1, lon=19.8, alt=100.0, kind=RadarKind.TWO_D),
}
LAGS = {"R1": 0.0, "R2": 1.0, "R3": 3.5}  # s behind this host's clock
T0 = time.time_ns()


def aircraft(t_ns: int) -> tuple[float, float, float]:
    """An aircraft at 5 km flying east at 200 m/s from 45.1° N, 19.9° E."""
    t = (t_ns - T0) / S
    return pymap3d.enu2geodetic(200.0 * t, 0.0, 5000.0, 45.1, 19.9, 0.0)


def plot_batch(rid: str, seq: int, t_end: int, rng) -> PlotBatch:
    """One plot of the aircraft at t_end (slant range σ 30 m, azimuth σ 1 mrad)."""
    s = SITES[rid]
    lat, lon, h = aircraft(t_end)
    az, _, rng_m = pymap3d.geodetic2aer(lat, lon, h, s.lat, s.lon, s.alt)
    return PlotBatch(
        radar_id=rid, scan=seq, seq=seq, time_start=t_end - S // 2, time_end=t_end,
        time=[t_end], range=[float(rng_m + rng.normal(0, 30.0))],
        azimuth=[float(np.deg2rad(az) + rng.normal(0, 1e-3)) % (2 * np.pi)], altitude=[h],
    )  # fmt: skip


def _last_status(inbox: Inbox, until) -> Status | None:
    st, deadline = None, time.monotonic() + 10
    while time.monotonic() < deadline:
        item = inbox.get(0.2)
        if item is not None:
            st = Status.from_json_bytes(item.payload)
            if until(st):
                break
    return st


def test_lagging_radar_is_applied_by_the_oosm_update(start_skyfuse):
    ep = f"tcp/127.0.0.1:{free_port()}"
    fusion = start_skyfuse(
        "fusion", "--listen", ep, "--reorder-wait", "0.2", "--status-interval", "0.25",
        "--frame-lat0", "45.1", "--frame-lon0", "20.0", log="fusion",
    )  # fmt: skip
    rng = np.random.default_rng(7)
    n = 24
    with open_session(TransportConfig(connect=[ep])) as s:
        assert wait_for_tokens(s, [service_alive_key("fusion")], 20.0) == []
        status, feed = Inbox(), Inbox()
        status.subscribe(s, keys.fusion_status("main"), "status")
        feed.subscribe(s, keys.fusion_tracks("main"), "tracks")
        pubs = {r: declare_publisher(s, keys.radar_plots(r)) for r in LAGS}
        for r, site in SITES.items():
            declare_publisher(s, keys.radar_site(r)).put(site.to_json_bytes())
        time.sleep(0.5)
        for k in range(n):
            now = time.time_ns()
            for r, lag in LAGS.items():
                b = plot_batch(r, k, now - round(lag * S), rng)
                pubs[r].put(b.to_json_bytes(), attachment=wall_stamp(now))
            time.sleep(0.5)
        st = _last_status(status, lambda st: st.counters.get("cycles", 0) >= 2 * n + 1)
        times = []
        while (item := feed.get(0.2)) is not None:
            times.append(TrackBatch.from_json_bytes(item.payload).time)
        status.close()
        feed.close()
    assert fusion.poll() is None
    assert st is not None and st.late is not None
    late = st.late
    assert st.counters["cycles"] >= 2 * n  # every R1 and R2 batch (and R3's first)
    # R2: 1 s behind the service time (its first batch may come in order: the service time
    # does not leap from R3's first batch 2.5 s ahead before later data confirms it)
    assert late.batches_late >= n - 2
    assert late.batches_oosm >= n - 6  # … all but the first few (before the track starts)
    assert late.plots_oosm >= n - 6 and late.hits_oosm >= n - 6
    assert late.track_updates_oosm >= late.batches_oosm
    assert late.batches_too_late >= n - 2 and st.rejected.get("too late") == late.batches_too_late
    assert late.max_lateness_s == 2.0
    assert st.tracks_confirmed >= 1
    assert len(times) > n and (np.diff(times) >= 0).all()  # the feed never goes back
