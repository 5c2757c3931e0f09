"""``skyfuse fusion --coalesce-max-deg 90`` as a process on loopback: a radar's 16-sector
batches of several revolutions arrive in one burst (the service is behind), so runs of
four contiguous sectors go through the tracker as one step each. Expected: Status counts
the coalesced steps and batches, every plot is applied, the deltas count every batch
they apply, and the aircraft in the burst gets a confirmed track."""

from __future__ import annotations

import math
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
SITE = RadarSite(radar_id="R1", lat=45.0, lon=20.0, alt=100.0, kind=RadarKind.TWO_D)
SECTORS, REVS, PERIOD = 16, 8, 4 * S


def sector_batches(t0: int, rng) -> list[PlotBatch]:
    """REVS revolutions of SECTORS batches from t0; an aircraft 50 km east of the radar
    at 5 km height flying north at 200 m/s is in the sector its azimuth falls in."""
    w, out = 2 * math.pi / SECTORS, []
    for k in range(REVS * SECTORS):
        rev, s = divmod(k, SECTORS)
        ts, te = t0 + k * PERIOD // SECTORS, t0 + (k + 1) * PERIOD // SECTORS
        t_rev = (t0 + rev * PERIOD - t0) / S
        lat, lon, h = pymap3d.enu2geodetic(50e3, 200.0 * t_rev, 5000.0, SITE.lat, SITE.lon, 0.0)
        az, _, r = pymap3d.geodetic2aer(lat, lon, h, SITE.lat, SITE.lon, SITE.alt)
        az = math.radians(az) % (2 * math.pi)
        inside = s * w <= az < (s + 1) * w
        t = [ts + round((az - s * w) / w * (te - ts))] if inside else []
        out.append(PlotBatch(
            radar_id="R1", scan=rev, seq=k, sector_start=s * w, sector_width=w,
            time_start=ts, time_end=te, time=t,
            range=[float(r + rng.normal(0, 30.0))] if inside else [],
            azimuth=[float(az + rng.normal(0, 1e-3))] if inside else [],
            altitude=[h] if inside else [],
        ))  # fmt: skip
    return out


def test_a_burst_of_sectors_is_coalesced_into_fewer_steps(start_skyfuse):
    ep = f"tcp/127.0.0.1:{free_port()}"
    fusion = start_skyfuse(
        "fusion", "--listen", ep, "--reorder-wait", "0.2", "--status-interval", "0.25",
        "--frame-lat0", "45.0", "--frame-lon0", "20.3", "--coalesce-max-deg", "90",
        "--bulk-max", "1000", log="fusion",
    )  # fmt: skip
    batches = sector_batches(time.time_ns() - REVS * PERIOD - S, np.random.default_rng(3))
    with open_session(TransportConfig(connect=[ep])) as s:
        assert wait_for_tokens(s, [service_alive_key("fusion")], 20.0) == []
        status, feed = Inbox(), Inbox()
        status.subscribe(s, keys.fusion_status("main"), "status")
        feed.subscribe(s, keys.fusion_tracks("main"), "tracks")
        declare_publisher(s, keys.radar_site("R1")).put(SITE.to_json_bytes())
        pub = declare_publisher(s, keys.radar_plots("R1"))
        time.sleep(0.5)
        for b in batches:  # one burst: all ready together after the reorder wait
            pub.put(b.to_json_bytes(), attachment=wall_stamp(time.time_ns()))
        st, deadline = None, time.monotonic() + 15
        while time.monotonic() < deadline:
            item = status.get(0.2)
            if item is not None:
                st = Status.from_json_bytes(item.payload)
                if st.counters.get("cycles", 0) >= len(batches):
                    break
        applied = 0
        while (item := feed.get(0.5)) is not None:
            tb = TrackBatch.from_json_bytes(item.payload)
            applied += tb.batches if tb.kind.value == "delta" else 0
        status.close()
        feed.close()
    assert fusion.poll() is None
    assert st is not None and st.counters["cycles"] == len(batches)
    assert st.counters["plots_applied"] == REVS
    # runs of at most 4 sectors (90°); how many depends on how the burst's arrival is cut
    # into groups by the reorder wait, so only a floor that any cut gives
    steps, members = st.counters["coalesced_steps"], st.counters["batches_coalesced"]
    assert steps >= REVS and members >= len(batches) // 2 and members <= 4 * steps
    assert applied == len(batches)  # each delta counts the batches it applies
    assert st.tracks_confirmed >= 1
