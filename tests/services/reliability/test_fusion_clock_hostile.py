"""``skyfuse fusion`` as a process against hostile and faulty clocks on loopback: a poison
batch far in the future (from a radar without a site), a radar lagging 1 s (more than the
reorder wait), a radar 3 s ahead. Expected: the poison and the leading radar's batches are
refused and counted, the lagging radar keeps contributing (applied late), the on-time
radar is never blocked, and every radar's clock offset is reported in Status."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from skyfuse.schemas import PlotBatch, RadarKind, RadarSite, Status, keys
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


def site(rid: str, lat: float) -> RadarSite:
    return RadarSite(radar_id=rid, lat=lat, lon=20.0, alt=100.0, kind=RadarKind.TWO_D)


def batch(rid: str, seq: int, t_end: int, rng) -> PlotBatch:
    n = 3
    times = np.sort(rng.integers(t_end - S // 4, t_end, n))
    return PlotBatch(
        radar_id=rid, scan=seq // 16, seq=seq, time_start=t_end - S // 4, time_end=t_end,
        time=times.tolist(), range=rng.uniform(5e3, 8e4, n).tolist(),
        azimuth=rng.uniform(0, 6.28, n).tolist(), altitude=rng.uniform(1e3, 9e3, n).tolist(),
    )  # fmt: skip


def test_fusion_survives_poison_future_lagging_and_leading_clocks(start_skyfuse, tmp_path):
    ep = f"tcp/127.0.0.1:{free_port()}"
    fusion = start_skyfuse(
        "fusion", "--listen", ep, "--reorder-wait", "0.2", "--status-interval", "0.25",
        "--frame-lat0", "45.0", "--frame-lon0", "20.0", log="fusion",
    )  # fmt: skip
    recorder = start_skyfuse("record", "--out", str(tmp_path / "r.mcap"), "--connect", ep,
                             "--status-interval", "0.25", log="recorder")  # fmt: skip
    rng = np.random.default_rng(3)
    lags = {"R1": 0.0, "R2": 1.0, "R3": -3.0}  # s behind this host's clock
    n = 12
    with open_session(TransportConfig(connect=[ep])) as s:
        alive = [service_alive_key("fusion"), service_alive_key("recorder")]
        assert wait_for_tokens(s, alive, 20.0) == []
        inbox = Inbox()
        inbox.subscribe(s, keys.fusion_status("main"), "status")
        rec_status = Inbox()
        rec_status.subscribe(s, keys.service_status("recorder"), "status")
        pubs = {r: declare_publisher(s, keys.radar_plots(r)) for r in [*lags, "R9"]}
        for i, r in enumerate(lags):
            declare_publisher(s, keys.radar_site(r)).put(site(r, 45.0 + 0.2 * i).to_json_bytes())
        time.sleep(0.5)
        # the int64 overflow that crashed fusion and recorder (exit 1) before the time guards
        overflow = batch("R1", 99, time.time_ns(), rng).model_dump()
        overflow["time"] = [2**64] * 3
        pubs["R1"].put(json.dumps(overflow).encode())
        poison = batch("R9", 0, time.time_ns() + 3600 * S, rng)
        pubs["R9"].put(poison.to_json_bytes(), attachment=wall_stamp())
        for k in range(n):
            now = time.time_ns()
            for r, lag in lags.items():
                b = batch(r, k, now - round(lag * S), rng)
                pubs[r].put(b.to_json_bytes(), attachment=wall_stamp(now))
            time.sleep(0.25)
        deadline = time.monotonic() + 10
        st = None
        while time.monotonic() < deadline:
            item = inbox.get(0.2)
            if item is not None:
                st = Status.from_json_bytes(item.payload)
                if st.counters.get("cycles", 0) >= 2 * n and st.counters.get("queued") == 0:
                    break
        inbox.close()
        rec = None
        for _ in range(40):  # the recorder's latest status (every 0.25 s)
            item = rec_status.get(0.5)
            if item is not None:
                rec = Status.from_json_bytes(item.payload)
                if rec.counters.get("messages", 0) >= 3 * n + 3 + 1:
                    break
        rec_status.close()
    assert fusion.poll() is None and recorder.poll() is None  # both still running
    assert rec is not None and rec.rejected == {"invalid PlotBatch": 1}
    assert rec.counters["messages"] >= 3 * n + 3 + 1  # every valid message recorded
    assert st is not None
    assert st.rejected.get("invalid PlotBatch: time") == 1
    assert st.rejected.get("time in the future") == 1 + n  # the poison and all of R3
    assert "out of sequence" not in st.rejected and "too late" not in st.rejected
    assert st.counters["cycles"] == 2 * n  # every R1 and R2 batch applied
    assert st.counters["batches_late_applied"] >= n - 1  # R2: 1 s behind, applied late
    radars = {r.radar_id: r for r in st.radars}
    assert radars["R1"].batches == n and radars["R2"].batches == n
    assert radars["R3"].batches == 0
    assert radars["R1"].clock_offset_s == pytest.approx(0.0, abs=0.1)
    assert radars["R2"].clock_offset_s == pytest.approx(-1.0, abs=0.1)
    assert radars["R3"].clock_offset_s == pytest.approx(3.0, abs=0.1)
    assert radars["R9"].clock_offset_s > 3000
