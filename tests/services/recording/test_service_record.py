"""``skyfuse record`` and ``skyfuse replay`` as real processes on loopback: no loss,
malformed input counted, clean SIGTERM stop, SIGKILL loses at most the last chunk,
rotation, and a finished file that passes ``pymcap-cli doctor``."""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import time
from collections import Counter

import pytest
from service_support import make_batch, make_site, peer, skyfuse, stop, synthetic_recording
from skyfuse.schemas import keys
from skyfuse.services.recording.mcap_io import ReadStats, iter_recording
from skyfuse.services.runtime.transport import (
    declare_publisher,
    free_port,
    loopback_endpoint,
    open_session,
    service_alive_key,
    wait_for_tokens,
)
from skyfuse.services.sensors.replay import replay

pytestmark = pytest.mark.service


def topic_counts(path) -> Counter:
    return Counter(r.topic for r in iter_recording(path, decode=False))


def test_replay_is_recorded_without_loss_and_stops_cleanly(tmp_path):
    src = tmp_path / "src.mcap"
    per_radar = synthetic_recording(src, scans=3, n_sectors=8)
    out, stats = tmp_path / "rec.mcap", tmp_path / "rec.json"
    ep = loopback_endpoint(free_port())
    proc = skyfuse(
        "record", "--out", str(out), "--listen", ep, "--stats", str(stats),
        "--flush-interval", "0.2", log_path=tmp_path / "rec.log",
    )  # fmt: skip
    try:
        with open_session(peer(connect=ep)) as s:
            assert wait_for_tokens(s, [service_alive_key("recorder")], 10.0) == []
            result = replay(s, src, fast=True)
            bad = declare_publisher(s, keys.radar_plots("R1"))
            bad.put(b'{"radar_id": "R1", "scan": -1}')  # malformed: counted, not recorded
            bad.put(b"not json at all")
            time.sleep(0.5)
    finally:
        rc, took = stop(proc)
    assert rc == 0, (tmp_path / "rec.log").read_text()
    assert took < 5.0
    assert result.published[keys.radar_plots("R1")] == per_radar["R1"]
    counts = topic_counts(out)
    for r, n in per_radar.items():
        assert counts[keys.radar_plots(r)] == n  # recorded == published
        assert counts[keys.radar_site(r)] == 1
    assert counts["/foxglove/plots"] == 2 * 3  # one per radar revolution
    assert counts["/foxglove/sites"] == 2 + 2 * 3  # on receipt, then with each scan
    summary = json.loads(stats.read_text())
    assert summary["rejected"] == {"invalid PlotBatch": 2}
    # contents are byte-identical to the source
    src_data = {(r.topic, r.data) for r in iter_recording(src, decode=False)}
    rec_data = {(r.topic, r.data) for r in iter_recording(out, decode=False)}
    assert src_data <= rec_data
    doctor = shutil.which("pymcap-cli")
    if doctor:
        res = subprocess.run([doctor, "doctor", str(out)], capture_output=True, timeout=60)
        assert res.returncode == 0, res.stdout.decode()[-2000:]


def test_killed_recorder_keeps_flushed_chunks_and_rotation(tmp_path):
    ep = loopback_endpoint(free_port())
    out = tmp_path / "rot.mcap"
    proc = skyfuse(
        "record", "--out", str(out), "--listen", ep, "--flush-interval", "0.1",
        "--rotate-mb", "0.002", "--no-foxglove", log_path=tmp_path / "rec.log",
    )  # fmt: skip
    import numpy as np

    rng = np.random.default_rng(3)
    sent = 0
    try:
        with open_session(peer(connect=ep)) as s:
            assert wait_for_tokens(s, [service_alive_key("recorder")], 10.0) == []
            pub_site = declare_publisher(s, keys.radar_site("R1"))
            pub = declare_publisher(s, keys.radar_plots("R1"))
            pub_site.put(make_site("R1", 45.0, 20.0).to_json_bytes())
            for burst in range(3):
                for k in range(4):
                    pub.put(make_batch("R1", burst, k, 4, 10, rng).to_json_bytes())
                    sent += 1
                time.sleep(0.4)  # > flush interval: the chunk is on disk, rotation checked
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=5)
    files = sorted(tmp_path.glob("rot-*.mcap"))
    assert len(files) >= 2, files
    recovered = 0
    for f in files:
        st = ReadStats()
        topics = [r.topic for r in iter_recording(f, stats=st)]
        recovered += topics.count(keys.radar_plots("R1"))
        assert keys.radar_site("R1") in topics  # every file carries the site
    assert recovered == sent


def test_foxglove_plot_positions_match_geodesic_range_and_bearing():
    import numpy as np
    from pyproj import Geod
    from skyfuse.schemas import PlotBatch, RadarKind, RadarSite
    from skyfuse.services.recording.recorder import plot_positions

    site = RadarSite(radar_id="R", lat=45.0, lon=20.0, alt=0.0, kind=RadarKind.THREE_D)
    for n in (1, 3):  # a single plot must work too
        az = [0.3, 2.0, 4.5][:n]
        b = PlotBatch(
            radar_id="R", scan=0, seq=0, time_start=0, time_end=1, time=[1] * n,
            range=[20_000.0] * n, azimuth=az, elevation=[0.0] * n,
        )  # fmt: skip
        lat, lon, _ = plot_positions(b, site)
        fwd, _, dist = Geod(ellps="WGS84").inv([site.lon] * n, [site.lat] * n, lon, lat)
        assert len(lat) == n
        # elevation 0 on a 20 km slant range: ground distance within 1 m of it
        assert abs(dist - 20_000.0).max() < 1.0
        dev = (np.asarray(fwd) - np.degrees(az) + 180) % 360 - 180
        assert abs(dev).max() < 0.01
