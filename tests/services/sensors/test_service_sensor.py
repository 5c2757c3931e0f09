"""``skyfuse sensor`` as a real process: publishes exactly its radar's (or ADS-B's) batches of the
scenario (compared with the offline simulator), the site also via queryable and
liveliness, stops on SIGTERM within 5 s, and rejects an unknown radar id with exit 2."""

from __future__ import annotations

import signal
import time

import pytest
from service_support import peer, skyfuse, stop
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.schemas import PlotBatch, RadarSite, keys
from skyfuse.services.runtime.transport import (
    Inbox,
    alive_tokens,
    free_port,
    loopback_endpoint,
    open_session,
    query,
    service_alive_key,
    wait_for_tokens,
)

pytestmark = pytest.mark.service

SCEN = ("--scenario", "regional", "--seed", "4", "--duration", "12", "--targets", "4")


@pytest.mark.parametrize("radar", ["LYBE", "ADSB"])
def test_sensor_publishes_its_radar_of_the_scenario(tmp_path, radar):
    """A radar, and the scenario's ADS-B network (a report sensor: one batch a cycle)."""
    extra = ("--param", "adsb=true") if radar == "ADSB" else ()
    sc = build_scenario("regional", seed=4, duration=12, targets=4, adsb=radar == "ADSB")
    site = next(x for x in sc.sites if x.radar_id == radar)
    expected = [
        ev.message.to_json_bytes()
        for ev in Simulator(sc, seed=4).run()
        if ev.kind == "plots" and ev.message.radar_id == radar
    ]
    ep = loopback_endpoint(free_port())
    with open_session(peer(listen=ep)) as s:
        inbox = Inbox()
        inbox.subscribe(s, keys.radar_plots(radar), "plots")
        inbox.subscribe(s, keys.radar_site(radar), "site")
        proc = skyfuse(
            "sensor", "--radar", radar, *SCEN, *extra, "--speed", "30", "--connect", ep,
            "--linger", "1.0", log_path=tmp_path / "sensor.log",
        )  # fmt: skip
        got, sites = [], []
        try:
            deadline = time.monotonic() + 15
            while len(got) < len(expected) and time.monotonic() < deadline:
                item = inbox.get(0.1)
                if item is not None:
                    (got if item.tag == "plots" else sites).append(item)
            # while the sensor lingers: liveliness and the site queryable
            assert alive_tokens(s, keys.ALL_ALIVE) == [keys.radar_alive(radar)]
            (_key, payload), *_ = query(s, keys.ALL_SITES)
            assert RadarSite.from_json_bytes(payload) == site
        finally:
            rc, _ = stop(proc, timeout=10)
    assert rc == 0, (tmp_path / "sensor.log").read_text()
    batches = [PlotBatch.from_json_bytes(g.payload) for g in got]
    epochs = {b.epoch for b in batches}
    assert len(epochs) == 1 and 0 not in epochs  # the epoch of this run's numbering
    # same batches, same order, unchanged but for the epoch
    assert [b.model_copy(update={"epoch": 0}).to_json_bytes() for b in batches] == expected
    assert RadarSite.from_json_bytes(sites[0].payload) == site
    # paced: wall stamps follow simulated time / speed
    t = [PlotBatch.from_json_bytes(g.payload).time_end for g in got]
    sim_span = (t[-1] - t[0]) / 1e9 / 30
    wall_span = (got[-1].sent_ns - got[0].sent_ns) / 1e9
    assert abs(wall_span - sim_span) < 0.01
    assert all(g.recv_ns >= g.sent_ns - 5e6 for g in got)


def test_sensor_sigterm_and_bad_radar(tmp_path):
    ep = loopback_endpoint(free_port())
    bad = skyfuse("sensor", "--radar", "NOPE", *SCEN, log_path=tmp_path / "bad.log")
    with open_session(peer(listen=ep)) as s:
        proc = skyfuse(
            "sensor", "--radar", "LYBE", *SCEN, "--speed", "1", "--connect", ep,
            log_path=tmp_path / "s.log",
        )  # fmt: skip
        assert wait_for_tokens(s, [service_alive_key("sensor-LYBE")], 15.0) == []
        rc, took = stop(proc, signal.SIGINT)
    assert rc == 0 and took < 5.0
    assert bad.wait(timeout=20) == 2
    assert "is not in scenario 'regional'" in (tmp_path / "bad.log").read_text()
