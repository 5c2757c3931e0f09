"""CAT010 / CAT021 reports → the PlotBatches of their sensors (multilateration, surface
movement radar, ADS-B): the real LEBL recordings checked against their reports decoded
independently of the batcher (``read_reports``), the batching rules on hand-made reports,
several recordings merged in time order, and input the wire contract refuses counted
without losing the reports around it."""

from __future__ import annotations

import datetime as dt
import math
import random

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from service_support import LEBL_SITES_TOML, SHARED_DATA
from skyfuse.schemas import PlotBatch, RadarKind
from skyfuse.services.asterix import (
    AsterixStreamDecoder,
    cat010,
    cat020,
    cat021,
    load_sites,
    merge_results,
    read_asterix,
)
from skyfuse.services.asterix.pcap import Datagram
from skyfuse.services.asterix.record_reject import RecordReject
from skyfuse.services.asterix.report_batches import ReportBatcher
from skyfuse.services.asterix.surveillance import read_reports
from skyfuse.services.evaluation.inputs import InputError, open_input

DAY = dt.date(2016, 5, 10)


@pytest.fixture(scope="module")
def lebl(tmp_path_factory):
    if not SHARED_DATA.is_dir():
        pytest.skip(f"{SHARED_DATA} is absent")
    path = tmp_path_factory.mktemp("lebl") / "lebl.toml"
    path.write_text(LEBL_SITES_TOML)
    files = {k: SHARED_DATA / f"lebl_20160510_2200_2215_{k}.ast" for k in ("mlat", "smr", "adsb")}
    return files, load_sites(path), path


def _reports(path):
    reports, _, _ = read_reports(path, date=DAY)
    return reports


def test_multilateration_batches_are_its_update_cycles_without_field_monitors(lebl):
    files, sites, _ = lebl
    res = read_asterix(files["mlat"], date=DAY, sites=sites)
    reports = _reports(files["mlat"])
    cycles = [r.time_ns for r in reports if isinstance(r, cat010.Cat010Status)
              and r.message_type == cat010.START_OF_UPDATE_CYCLE]  # fmt: skip
    targets = [r for r in reports if isinstance(r, cat010.Cat010Report)]
    kept = [r for r in targets if not r.rab]
    assert res.stats["report_field_monitors"] == len(targets) - len(kept) == 5220
    assert set(res.radars) == {"0-107"} and res.radars["0-107"] == len(kept) == res.n_plots
    # every cycle message closes a batch; before the first one the reports go in 1-s
    # windows, after the last one the end of the file closes the batch
    ends = [b.time_end for b in res.batches]
    assert set(cycles) <= set(ends)
    assert all(e < cycles[0] or e > cycles[-1] for e in set(ends) - set(cycles))
    site = res.sites["0-107"]
    assert site.kind is RadarKind.CARTESIAN and site.detection == "reports"
    assert site.scan_period == pytest.approx(1.0, abs=1e-3)
    assert res.scan_period_source["0-107"] == "cycle"
    # the plots are the reports, in time order, one per track and batch
    by_time = {(r.time_ns, r.x_m, r.y_m): r for r in kept}
    for b in res.batches:
        t = b.column("time")
        assert (np.diff(t) >= 0).all() and b.time_start <= t.min() and t.max() <= b.time_end
        for ti, x, y, s in zip(t.tolist(), b.x, b.y, b.mode_s):
            assert by_time[(ti, x, y)].mode_s == s
    assert sum(len(b) for b in res.batches) == len(by_time)


def test_surface_radar_batches_are_cartesian_sorted_without_track_ends(lebl):
    """The SMR's plots are its I042 positions (x east, y north of its site), σ per axis
    √(σ_c² + L²/12) with L its target's length, in time order; track ends dropped."""
    files, sites, _ = lebl
    res = read_asterix(files["smr"], date=DAY, sites=sites)
    reports = [r for r in _reports(files["smr"]) if isinstance(r, cat010.Cat010Report)]
    ends = [r for r in reports if r.rho_m is None and r.x_m is None]
    assert res.stats["report_track_ends"] == len(ends) == 109
    site = res.sites["0-7"]
    assert site.kind is RadarKind.CARTESIAN and site.detection == "reports"
    assert site.report_timeout == 10.0 and site.timing == "plots"
    assert site.max_altitude == pytest.approx(site.alt + 300.0)
    plotted = {(r.time_ns, r.x_m, r.y_m): r for r in reports if r.x_m is not None}
    seen = set()
    for b in res.batches:
        assert (np.diff(b.column("time")) >= 0).all()
        for t, x, y, s in zip(b.time, b.x, b.y, b.sigma or [None] * len(b)):
            seen.add((t, x, y))
            L = plotted[(t, x, y)].length_m
            want = math.sqrt(site.sigma_cartesian**2 + L**2 / 12) if L else None
            assert s == pytest.approx(want) if want else s is None
    assert seen == set(plotted)
    # the stream steps back in time within a cycle (sweep order); the batches do not
    times = [r.time_ns for r in reports if r.x_m is not None]
    assert (np.diff(times) < 0).sum() > 900


def test_adsb_batches_are_windows_with_one_report_per_aircraft_and_their_sigma(lebl):
    files, sites, _ = lebl
    res = read_asterix(files["adsb"], date=DAY, sites=sites)
    reports = [r for r in _reports(files["adsb"]) if isinstance(r, cat021.Cat021Report)]
    no_sigma = sum(r.sigma_pos_m is None for r in reports)
    assert res.stats["adsb_no_accuracy"] == no_sigma > 0
    assert res.n_plots == len(reports) - no_sigma
    assert set(res.radars) == {"0-107-adsb"}
    site = res.sites["0-107-adsb"]
    # no table of its own: anchored at its SAC/SIC's multilateration site
    assert (site.lat, site.lon, site.kind) == (sites["0-107"].lat, sites["0-107"].lon, "wgs84")
    sigma = {(r.time_ns, r.address): r.sigma_pos_m for r in reports}
    window = 1_000_000_000
    for b in res.batches:
        assert len(set(b.mode_s)) == len(b)  # one report per aircraft
        assert b.time_end - b.time_start <= window
        # a window never straddles a multiple of the window length
        assert (b.time_start // window) == ((b.time_end - 1) // window)
        for t, a, s in zip(b.time, b.mode_s, b.sigma):
            assert s == pytest.approx(sigma[(t, a)])
    assert res.stats["report_batch_split"] > 0
    # an empirical σ for every report, and the reports without a quality kept then
    res2 = read_asterix(files["adsb"], date=DAY, sites=sites, adsb_sigma=6.0)
    assert res2.n_plots == len(reports)
    assert {s for b in res2.batches for s in b.sigma} == {6.0}


def _mlat(tod, track, x=100.0, y=200.0, **kw):
    r = cat010.Cat010Report(0, 107, tod, typ=1, x_m=x, y_m=y, track_number=track, **kw)
    r.time_ns = round(tod * 1e9)
    return r


def _cycle(tod):
    s = cat010.Cat010Status(0, 107, cat010.START_OF_UPDATE_CYCLE, tod)
    s.time_ns = round(tod * 1e9)
    return s


def _run(items, **kw) -> tuple[list[PlotBatch], ReportBatcher]:
    b = ReportBatcher(**kw)
    out = [batch for it in items for batch, _ in b.add(it)]
    return out + [batch for batch, _ in b.flush()], b


def test_batching_rules_on_hand_made_reports():
    # cycles: reports between cycle messages; an empty cycle is an empty batch; a repeated
    # track closes the batch; RAB (field monitor), test-less track ends counted
    items = [_cycle(10.0), _mlat(10.1, 1), _mlat(10.2, 2), _mlat(10.3, 1), _cycle(11.0),
             _cycle(12.0), _mlat(12.5, 3, rab=True), _mlat(12.6, 4, x=None, y=None, last=True),
             _mlat(12.7, 5)]  # fmt: skip
    batches, b = _run(items)
    assert [len(x) for x in batches] == [2, 1, 0, 1]
    assert [x.time_end for x in batches[:3]] == [int(10.2e9), int(11e9), int(12e9)]
    assert batches[1].time_start == int(10.2e9) and batches[2].time_start == int(11e9)
    assert b.stats["report_batch_split"] == 1 and b.stats["report_field_monitors"] == 1
    assert b.stats["report_track_ends"] == 1
    assert [x.seq for x in batches] == [0, 1, 2, 3]
    # no cycle messages: fixed windows; no window without reports
    batches, _ = _run([_mlat(3.2, 1), _mlat(3.9, 2), _mlat(6.1, 1), _mlat(6.4, 2)], window=1.0)
    assert [(x.time_start, x.time_end, len(x)) for x in batches] == [
        (int(3e9), int(4e9), 2), (int(6e9), int(6.4e9), 2)]  # fmt: skip
    # the cycles stop: windows after three periods without one
    items = [_cycle(1.0), _mlat(1.5, 1), _cycle(2.0), _mlat(2.5, 1), _cycle(3.0), _mlat(3.5, 1),
             _mlat(7.2, 1), _mlat(7.5, 2)]  # fmt: skip
    batches, b = _run(items, window=1.0)
    assert b.stats["report_cycles_lost"] == 1
    assert batches[-1].time_start == int(7e9) and len(batches[-1]) == 2


def test_adsb_reports_without_quality_and_other_types():
    a = cat021.Cat021Report(0, 107, "0.23", 5.0, 41.3, 2.1, 0x3433D5, sigma_pos_m=None)
    a.time_ns = int(5e9)
    psr_loop = _mlat(5.0, 9)
    psr_loop.typ = 4  # magnetic loop: not tracked
    batches, b = _run([a, psr_loop])
    assert batches == [] and b.stats["adsb_no_accuracy"] == 1
    assert b.stats["report_type_not_tracked"] == 1


def test_recordings_are_merged_in_time_order_and_a_sensor_in_two_is_refused(lebl):
    files, sites, sites_path = lebl
    m = read_asterix(files["mlat"], date=DAY, sites=sites)
    s = read_asterix(files["smr"], date=DAY, sites=sites)
    merged = merge_results([s, m], ["smr", "mlat"])
    keys = [(b.time_end, b.radar_id, b.seq) for b in merged.batches]
    assert keys == sorted(keys) and len(keys) == len(m.batches) + len(s.batches)
    assert merged.radars == {**m.radars, **s.radars}
    # each sensor's site comes from its own recording (its kind, its cycle)
    assert merged.sites["0-107"].kind == "cartesian" and merged.sites["0-7"].detection == "reports"
    with pytest.raises(ValueError, match="0-107 is in both"):
        merge_results([m, m], ["a", "b"])
    src = open_input([files["smr"], files["mlat"]], sites_file=sites_path, date=DAY)
    assert [(b.time_end, b.radar_id, b.seq) for b in src.messages()] == keys
    with pytest.raises(InputError, match="is in both"):
        open_input([files["mlat"], files["mlat"]], sites_file=sites_path, date=DAY)


# ---- input that decodes but breaks the wire contract ------------------------------------
# A corrupted I041 latitude, I202 velocity or cycle time went through decoding and crashed
# the batcher when the PlotBatch refused it (found by mutating the LEBL recordings): now a
# counted rejection, and the good reports around it are kept.


def test_a_report_the_wire_contract_refuses_is_dropped_and_its_batch_kept():
    notes = []
    b = ReportBatcher(note=notes.append)
    items = [_cycle(10.0), _mlat(10.1, 1, vx_ms=3.0, vy_ms=4.0),
             _mlat(10.2, 2, vx_ms=5000.0, vy_ms=0.0), _mlat(10.3, 3, vx_ms=1.0, vy_ms=1.0),
             _cycle(11.0)]  # fmt: skip
    out = [batch for it in items for batch, _ in b.add(it)] + [x for x, _ in b.flush()]
    assert [len(x) for x in out] == [2]
    assert list(out[0].v_east) == [3.0, 1.0]
    assert b.stats["report_invalid"] == 1 and b.stats["report_plots"] == 2
    dropped = [n for n in notes if "report dropped" in n]
    assert len(dropped) == 1 and "v_east" in dropped[0] and "5000" in dropped[0]


def test_a_cycle_message_timed_before_its_batch_is_counted():
    batches, b = _run([_cycle(10.0), _mlat(10.5, 1), _cycle(11.0), _cycle(5.0), _mlat(5.5, 2)])
    assert b.stats["report_cycle_time_backwards"] == 1
    assert all(x.time_start <= x.time_end for x in batches)
    assert sum(len(x) for x in batches) == 2


def test_an_adsb_sensor_without_a_wgs84_first_report_has_no_site_and_no_crash():
    r = _mlat(3.0, 1)
    r.typ = 2  # CAT010 ADS-B, but I042 only
    batches, b = _run([r])
    assert b.site_of(next(iter(b._sensors.values()))) is None
    assert sum(len(x) for x in batches) == 1


def _lat_lon(lat_deg: float, lon_deg: float, lsb: float) -> bytes:
    return round(lat_deg / lsb).to_bytes(4, "big", signed=True) + round(lon_deg / lsb).to_bytes(
        4, "big", signed=True
    )


@pytest.mark.parametrize(
    ("decode", "lsb", "reason"),
    [
        (cat010.decode_items, 180.0 / 2**31, "cat010_bad_position"),
        (cat020.decode_items, 180.0 / 2**25, "cat020_bad_position"),
    ],
)
def test_wgs84_positions_outside_their_ranges_are_rejected(decode, lsb, reason):
    base = {"010": bytes([0, 107]), "140": (3600 * 128).to_bytes(3, "big")}
    if decode is cat010.decode_items:
        base |= {"000": bytes([1]), "020": bytes([0x20])}
    good = decode({**base, "041": _lat_lon(41.3, 2.08, lsb)})
    assert not isinstance(good, RecordReject) and abs(good.lat - 41.3) < 1e-5
    bad = decode({**base, "041": _lat_lon(120.0 if lsb < 1e-7 else 900.0, 2.08, lsb)})
    assert isinstance(bad, RecordReject) and bad.reason == reason
    assert "041" in bad.detail and "outside WGS-84" in bad.detail
    assert reason in (cat010.REJECT_REASONS if "010" in reason else cat020.REJECT_REASONS)


def test_cat021_uses_the_same_reject():
    rec = cat021.decode_items({}, "2.7")
    assert isinstance(rec, RecordReject) and rec.reason == "cat021_no_data_source"


def _blocks(name: str, n: int) -> list[bytes]:
    data = (SHARED_DATA / name).read_bytes()[:300_000]
    out, pos = [], 0
    while pos + 3 <= len(data) and len(out) < n:
        length = int.from_bytes(data[pos + 1 : pos + 3], "big")
        out.append(data[pos : pos + length])
        pos += length
    return out


LEBL = [
    "lebl_20160510_2200_2215_smr.ast",
    "lebl_20160510_2200_2215_mlat.ast",
    "lebl_20160510_2200_2215_adsb.ast",
    "lebl_20201002_0800_0815_smr.ast",
]


@pytest.mark.skipif(not (SHARED_DATA / LEBL[0]).exists(), reason="shared LEBL data absent")
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(name=st.sampled_from(LEBL), seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6))
def test_mutated_lebl_records_never_crash_the_reader(name, seed, n):
    rng = random.Random(seed)
    chunk = bytearray(b"".join(rng.sample(_blocks(name, 600), 8)))
    for _ in range(n):
        chunk[rng.randrange(len(chunk))] = rng.randrange(256)
    dec = AsterixStreamDecoder(dedup=True)
    batches = [b for b, _ in dec.feed_with_types(Datagram(bytes(chunk), 0))]
    batches += dec.flush()
    assert sum(len(b) for b in batches) == dec.stats["report_plots"]
