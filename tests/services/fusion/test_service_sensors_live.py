"""The LEBL surface movement radar, multilateration and ADS-B recordings replayed live —
one ``skyfuse sensor --asterix`` process per sensor, in step (``--start-at`` and
``--data-start``) — into one ``skyfuse fusion`` process give the tracks of ``skyfuse track``
on the same three files: the same confirmed track ids after every live delta and the same
final states (the fusion batch by batch: ``--coalesce-max-deg off``; no periodic full
picture, whose tracks are predicted to the wall-clock instant it is sent)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from service_support import (
    LEBL_SITES_TOML,
    SHARED_DATA,
    confirmed_ids,
    feed_pictures,
    peer,
    skyfuse,
    stop,
)
from skyfuse.schemas import PlotBatch, TrackBatch, keys
from skyfuse.services.asterix import AsterixStreamDecoder
from skyfuse.services.cli.main import main as skyfuse_main
from skyfuse.services.evaluation.inputs import open_input
from skyfuse.services.recording.mcap_io import iter_recording
from skyfuse.services.runtime.transport import (
    Inbox,
    declare_liveliness,
    free_port,
    loopback_endpoint,
    open_session,
    service_alive_key,
    wait_for_tokens,
)

pytestmark = pytest.mark.service

DATE = "2016-05-10"
FIRST_TOD, LAST_TOD = 79203.0, 79243.0  # 22:00:03-22:00:43 (no two batches end together)


def stretch(src: Path, out: Path) -> Path:
    """The data blocks of a raw recording whose records are timed in [FIRST_TOD, LAST_TOD)."""
    data, off, keep = src.read_bytes(), 0, []
    reports: list = []
    dec = AsterixStreamDecoder(report_sink=reports.append, report_batches=False)
    while off + 3 <= len(data):
        n = int.from_bytes(data[off + 1 : off + 3], "big")
        block, off = data[off : off + n], off + n
        before = len(reports)
        dec.feed(block)
        if len(reports) > before and FIRST_TOD <= reports[before].tod < LAST_TOD:
            keep.append(block)
    out.write_bytes(b"".join(keep))
    return out


def test_three_lebl_sensors_live_through_fusion_equal_offline_track(tmp_path):
    names = ("smr", "mlat", "adsb")
    srcs = [SHARED_DATA / f"lebl_20160510_2200_2215_{k}.ast" for k in names]
    if not all(p.is_file() for p in srcs):
        pytest.skip(f"the LEBL recordings are not in {SHARED_DATA}")
    sites = tmp_path / "lebl.toml"
    sites.write_text(LEBL_SITES_TOML)
    files = [stretch(p, tmp_path / f"{k}.ast") for p, k in zip(srcs, names)]
    merged = [b for b in open_input(files, sites_file=sites, date=DATE).messages()]
    ends = [b.time_end for b in merged]
    assert len(set(ends)) == len(ends)  # no ties: live and offline order them alike
    assert {b.radar_id for b in merged} == {"0-7", "0-107", "0-107-adsb"}
    offline = tmp_path / "offline.mcap"
    common = ["--sites", str(sites), "--date", DATE]
    assert skyfuse_main(["track", *map(str, files), *common, "--out", str(offline),
                         "--no-progress"]) == 0  # fmt: skip
    off = [r.message for r in iter_recording(offline) if isinstance(r.message, TrackBatch)]
    ep = loopback_endpoint(free_port())
    fusion = skyfuse("fusion", "--listen", ep, "--reorder-wait", "1.0", "--coalesce-max-deg",
                     "off", "--full-interval", "3600",
                     log_path=tmp_path / "fusion.log")  # fmt: skip
    live, sensors = _run_live(tmp_path, ep, files, common, ends[0], len(merged))
    for i, p in enumerate(sensors):  # each ends on its own after its last batch
        try:
            rc = p.wait(timeout=30)
        finally:
            stop(p)
        assert rc == 0, (tmp_path / f"sensor{i}.log").read_text()[-2000:]
    rc, took = stop(fusion)
    assert rc == 0 and took < 5.0, (tmp_path / "fusion.log").read_text()[-3000:]
    pl, po = feed_pictures(live), dict(feed_pictures(off))
    assert len(po) == len(merged) and pl[-1][0] == len(merged)
    assert live[0].frame == off[0].frame
    assert [confirmed_ids(b) for _, b in pl] == [confirmed_ids(po[n]) for n, _ in pl]
    final_live, final_off = pl[-1][1], po[len(merged)]
    assert len(confirmed_ids(final_off)) >= 5  # surface and airborne traffic: not vacuous
    assert [t.track_id for t in final_live.tracks] == [t.track_id for t in final_off.tracks]
    for a, b in zip(final_live.tracks, final_off.tracks):
        np.testing.assert_allclose(a.state, b.state, rtol=0, atol=1e-6)


def _run_live(tmp_path, ep, files, common, first_end_ns, n_batches):
    """Three sensor processes in step: each decodes its file and waits for the test's go
    (``--wait-for``), then all start at the same next multiple of 4 s (``--align``); the
    TrackBatches the fusion published."""
    live: list[TrackBatch] = []
    data_start = f"{(first_end_ns - 500_000_000) / 1e9:.3f}"
    radars = ("0-7", "0-107", "0-107-adsb")
    with open_session(peer(connect=ep)) as s:
        inbox = Inbox()
        inbox.subscribe(s, keys.fusion_tracks("main"), "tracks")
        assert wait_for_tokens(s, [service_alive_key("fusion")], 20.0) == []
        sensors = [
            skyfuse("sensor", "--asterix", str(f), "--radar", r, *common, "--speed", "4",
                    "--align", "4", "--data-start", data_start, "--connect", ep,
                    "--wait-for", "fusion,test-go", "--wait-timeout", "120",
                    log_path=tmp_path / f"sensor{i}.log")
            for i, (f, r) in enumerate(zip(files, radars))
        ]  # fmt: skip
        ready = [service_alive_key(f"sensor-{r}") for r in radars]
        assert wait_for_tokens(s, ready, 100.0) == []
        while time.time() % 4.0 < 0.8 or time.time() % 4.0 > 1.2:  # far from a boundary
            time.sleep(0.02)
        go = declare_liveliness(s, service_alive_key("test-go"))
        deadline, applied = time.monotonic() + 60, 0
        while applied < n_batches and time.monotonic() < deadline:
            item = inbox.get(0.2)
            if item is not None:
                live.append(TrackBatch.from_json_bytes(item.payload))
                applied += live[-1].batches
        inbox.close()
        go.undeclare()
    assert applied == n_batches, f"{applied} of {n_batches} batches applied"
    return live, sensors


def test_plot_batches_of_the_stretch_are_report_batches(tmp_path):
    """The stretch holds each sensor's batches (a check of the slicing itself)."""
    src = SHARED_DATA / "lebl_20160510_2200_2215_mlat.ast"
    if not src.is_file():
        pytest.skip(f"{src} absent")
    f = stretch(src, tmp_path / "m.ast")
    sites = tmp_path / "s.toml"
    sites.write_text(LEBL_SITES_TOML)
    batches = [b for b in open_input(f, sites_file=sites, date=DATE).messages()]
    assert all(isinstance(b, PlotBatch) and b.radar_id == "0-107" for b in batches)
    assert 38 <= len(batches) <= 42  # one per 1-s update cycle
