"""Round trip: synthetic PlotBatches → CAT048/CAT034 bytes → reader gives the same
sectors and plots to ASTERIX resolution (LSBs from the CAT048/CAT034 specifications)."""

from __future__ import annotations

import datetime as dt
import math
from collections import Counter

import numpy as np
import pytest
from skyfuse.schemas import PlotBatch, RadarSite
from skyfuse.services.asterix import AsterixStreamDecoder, read_asterix
from skyfuse.services.asterix.pcap import build_pcap, split_datablocks
from skyfuse.services.asterix.writer import AsterixPlotWriter

NM = 1852.0
LSB_T = 1e9 / 128  # ns
LSB_RHO = NM / 256  # m
LSB_THETA = 2 * math.pi / 65536  # rad
LSB_FL_M = 0.25 * 100 * 0.3048  # m


def synthetic_batches(
    radar_id: str,
    t0_ns: int,
    *,
    period: float = 4.0,
    sectors: int = 16,
    scans: int = 3,
    seed: int = 1,
    per_sector: float = 3.0,
) -> list[PlotBatch]:
    """Sector batches of a clockwise radar: plot times follow the beam (t = t_sector_start
    + Δaz / ω), so every plot lies in its sector in both azimuth and time."""
    rng = np.random.default_rng(seed)
    w = 2 * math.pi / sectors
    out = []
    for k in range(scans * sectors):
        ts = t0_ns + round(k * period / sectors * 1e9)
        te = t0_ns + round((k + 1) * period / sectors * 1e9)
        m = int(rng.poisson(per_sector))
        frac = np.sort(rng.uniform(0.01, 0.99, m))
        az = (k % sectors) * w + frac * w
        t = (ts + frac * (te - ts)).round().astype(np.int64)
        out.append(
            PlotBatch(
                radar_id=radar_id,
                scan=k // sectors,
                seq=k,
                sector_start=(k % sectors) * w,
                sector_width=w,
                time_start=ts,
                time_end=te,
                time=t.tolist(),
                range=rng.uniform(500.0, 450_000.0, m).tolist(),
                azimuth=az.tolist(),
                altitude=[
                    None if rng.random() < 0.3 else float(rng.uniform(-300.0, 13_000.0))
                    for _ in range(m)
                ],
                amplitude=[
                    None if rng.random() < 0.5 else float(rng.uniform(-90, -40)) for _ in range(m)
                ],
                mode_s=[
                    int(rng.integers(0, 2**24)) if rng.random() < 0.5 else None for _ in range(m)
                ],
                mode_3a=[
                    int(rng.integers(0, 4096)) if rng.random() < 0.6 else None for _ in range(m)
                ],
            )
        )
    return out


def assert_same_plots(sent: list[PlotBatch], got: list[PlotBatch]) -> None:
    assert len(got) == len(sent)
    for a, b in zip(sent, got):
        assert (b.radar_id, b.scan, b.seq, len(b)) == (a.radar_id, a.scan, a.seq, len(a))
        assert b.sector_start == pytest.approx(a.sector_start, abs=1e-9)
        assert b.sector_width == pytest.approx(a.sector_width, abs=1e-9)
        assert abs(b.time_start - a.time_start) <= LSB_T / 2 + 1
        assert abs(b.time_end - a.time_end) <= LSB_T / 2 + 1
        if not len(a):
            continue
        # rounding to the LSB: |error| <= LSB/2 (time may move one more LSB to stay in sector)
        assert np.abs(b.column("time") - a.column("time")).max() <= 1.5 * LSB_T
        assert np.abs(b.column("range") - a.column("range")).max() <= LSB_RHO / 2 + 1e-9
        daz = (b.column("azimuth") - a.column("azimuth") + math.pi) % (2 * math.pi) - math.pi
        assert np.abs(daz).max() <= LSB_THETA / 2 + 1e-12
        for x, y in zip(a.altitude, b.altitude):
            assert (x is None) == (y is None)
            if x is not None:
                assert abs(x - y) <= LSB_FL_M / 2 + 1e-9
        for x, y in zip(a.amplitude, b.amplitude):
            assert (x is None) == (y is None)
            if x is not None:
                assert abs(x - y) <= 0.5
        assert b.mode_s == a.mode_s
        assert b.mode_3a == a.mode_3a


T0 = int(dt.datetime(2026, 3, 1, 10, 0, tzinfo=dt.UTC).timestamp()) * 10**9


def test_round_trip_raw_file(tmp_path):
    sent = synthetic_batches("20-129", T0)
    writer = AsterixPlotWriter()
    path = tmp_path / "sim.ast"
    path.write_bytes(writer.encode(sent))
    result = read_asterix(path, date=dt.date(2026, 3, 1))
    assert_same_plots(sent, result.batches)
    assert result.stats["cat048_simulated"] == sum(len(b) for b in sent)
    assert writer.stats["north_markers"] == 4  # the opening one + one per revolution


def test_round_trip_two_radars_through_pcap_and_site_messages(tmp_path):
    site = RadarSite(radar_id="20-129", lat=41.300702, lon=2.102058, alt=27.0, kind="2d")
    site = site.model_copy(update={"scan_period": 4.0})
    a = synthetic_batches("20-129", T0, seed=2)
    b = synthetic_batches("20-130", T0 + 123_456_789, period=6.0, sectors=32, scans=2, seed=3)
    writer = AsterixPlotWriter({"20-129": site})
    merged = sorted(a + b, key=lambda x: x.time_end)
    packets = []
    for batch in merged:
        packets.extend((batch.time_end, blk) for blk in writer.encode_batch(batch))
    path = tmp_path / "sim.pcap"
    path.write_bytes(build_pcap(packets))
    result = read_asterix(path)  # date from the capture times
    assert_same_plots(a, [x for x in result.batches if x.radar_id == "20-129"])
    assert_same_plots(b, [x for x in result.batches if x.radar_id == "20-130"])
    got = result.sites["20-129"]  # from CAT034 I120 and I041 (no sites file)
    assert got.lat == pytest.approx(site.lat, abs=180 / 2**23)
    assert got.lon == pytest.approx(site.lon, abs=180 / 2**23)
    assert got.alt == pytest.approx(site.alt, abs=0.5)
    assert got.scan_period == pytest.approx(4.0, abs=1 / 128)
    assert result.scan_period_source["20-129"] == "cat034"
    assert "20-130" not in result.sites  # no position known for it: reported, not invented
    assert any("20-130" in m and "no position" in m for m in result.messages)


def test_stream_decoder_emits_each_sector_when_it_closes():
    sent = synthetic_batches("20-129", T0, scans=1)
    writer = AsterixPlotWriter()
    dec = AsterixStreamDecoder(date=dt.date(2026, 3, 1))
    got: list[PlotBatch] = []
    for batch in sent:
        emitted = []
        for blk in writer.encode_batch(batch):
            emitted += dec.feed(blk, batch.time_end)
        # the closing sector crossing is the last block: the batch comes out at once
        assert [e.seq for e in emitted] == [batch.seq]
        got += emitted
    assert dec.flush() == []
    assert_same_plots(sent, got)


def test_midnight_roll_over_with_a_fixed_date(tmp_path):
    t0 = int(dt.datetime(2026, 3, 1, 23, 59, 58, tzinfo=dt.UTC).timestamp()) * 10**9
    sent = synthetic_batches("1-2", t0, scans=2)
    path = tmp_path / "midnight.ast"
    path.write_bytes(AsterixPlotWriter().encode(sent))
    result = read_asterix(path, date=dt.date(2026, 3, 1))
    assert_same_plots(sent, result.batches)
    times = [t for b in result.batches for t in b.time]
    assert times == sorted(times) and times[-1] - times[0] > 2 * 10**9


@pytest.mark.parametrize("n_sectors", [16, 4, 1])
def test_without_cat034_fixed_sectors_and_estimated_scan_period(tmp_path, n_sectors):
    """Fixed sectors of 2π/n (``--sector-count``): with one sector per turn too, where the
    boundary is the beam passing north (it used to be crossed only after a silent half
    turn, so a busy radar gave one batch for the whole recording)."""
    period = 4.8
    sent = synthetic_batches("7-9", T0, period=period, scans=6, per_sector=6.0, seed=5)
    blocks = []
    writer = AsterixPlotWriter()
    for batch in sent:
        for blk in writer.encode_batch(batch):
            blocks.extend(
                bytes([cat]) + (len(d) + 3).to_bytes(2, "big") + d
                for cat, d in split_datablocks(blk, Counter())
                if cat == 48
            )
    path = tmp_path / "nocat034.ast"
    path.write_bytes(b"".join(blocks))
    site = RadarSite(radar_id="7-9", lat=45.0, lon=16.0, alt=100.0, kind="2d")
    result = read_asterix(
        path, date=dt.date(2026, 3, 1), sites={"7-9": site}, sector_count=n_sectors
    )
    assert result.stats.get("cat034_records", 0) == 0
    assert result.n_plots == sum(len(b) for b in sent)
    assert result.scan_period_source["7-9"] == "estimated"
    assert result.sites["7-9"].scan_period == pytest.approx(period, rel=1e-3)
    w = 2 * math.pi / n_sectors
    assert len(result.batches) >= 5 * n_sectors  # the first sector opens at the first plot
    for b in result.batches:
        assert b.sector_width == pytest.approx(w)
        for a in b.azimuth or []:
            assert (a - b.sector_start) % (2 * math.pi) <= w + 1e-9
    # contiguous sectors: each starts where the previous ended
    for b1, b2 in zip(result.batches, result.batches[1:]):
        assert b2.sector_start == pytest.approx((b1.sector_start + w) % (2 * math.pi))
        assert b2.time_start == b1.time_end
    assert max(b.scan for b in result.batches) == 5


def test_writer_rejects_what_cat048_cannot_carry():
    cart = PlotBatch(
        radar_id="1-1", scan=0, seq=0, time_start=0, time_end=1, time=[1], x=[0.0], y=[0.0]
    )
    with pytest.raises(ValueError, match="polar"):
        AsterixPlotWriter().encode_batch(cart)
    far = PlotBatch(
        radar_id="1-1",
        scan=0,
        seq=0,
        time_start=0,
        time_end=10,
        time=[1, 2],
        range=[100_000.0, 300 * NM],
        azimuth=[0.1, 0.2],
    )
    writer = AsterixPlotWriter()
    writer.encode_batch(far)
    assert writer.stats["plot_beyond_256_nm"] == 1 and writer.stats["plots"] == 1
    named = far.model_copy(update={"radar_id": "radar_a"})
    with pytest.raises(ValueError, match=r"SAC-SIC.*sac_sic"):
        AsterixPlotWriter().encode_batch(named)
    blocks = AsterixPlotWriter(sac_sic={"radar_a": (9, 3)}).encode_batch(named)
    dec = AsterixStreamDecoder()
    for blk in blocks:
        dec.feed(blk, 1)
    assert dec.radars == {"9-3": 1}


def test_simulator_batches_round_trip(tmp_path):
    """The project's own simulator (4 radars, two of them 3-D) → CAT048/CAT034 → reader."""
    from skyfuse.fusion.sim.scenarios import build_scenario
    from skyfuse.fusion.sim.simulator import Simulator

    scenario = build_scenario("regional", duration=20.0, targets=6)
    sent = [e.message for e in Simulator(scenario).run() if e.kind == "plots"]
    ids = sorted({b.radar_id for b in sent})
    mapping = {rid: (30, 1 + i) for i, rid in enumerate(ids)}
    writer = AsterixPlotWriter(sac_sic=mapping)
    path = tmp_path / "regional.ast"
    path.write_bytes(writer.encode(sorted(sent, key=lambda b: b.time_end)))
    day = dt.datetime.fromtimestamp(min(b.time_start for b in sent) / 1e9, dt.UTC).date()
    result = read_asterix(path, date=day)
    assert writer.stats["dropped_elevation_column"] > 0  # the 3-D radars' elevations
    for rid, (sac, sic) in mapping.items():
        a = [b for b in sent if b.radar_id == rid]
        got = [b for b in result.batches if b.radar_id == f"{sac}-{sic}"]
        assert [len(b) for b in got] == [len(b) for b in a]
        for x, y in zip(a, got):
            assert y.sector_start == pytest.approx(x.sector_start, abs=1e-9)
            if not len(x):
                continue
            assert np.abs(y.column("time") - x.column("time")).max() <= 1.5 * LSB_T
            assert np.abs(y.column("range") - x.column("range")).max() <= LSB_RHO / 2 + 1e-9
            d = (y.column("azimuth") - x.column("azimuth") + math.pi) % (2 * math.pi) - math.pi
            assert np.abs(d).max() <= LSB_THETA / 2 + 1e-12
            if x.altitude is not None:
                alt_x, alt_y = x.column("altitude"), y.column("altitude")
                assert np.array_equal(np.isnan(alt_x), np.isnan(alt_y))
                ok = ~np.isnan(alt_x)
                assert np.abs(alt_y[ok] - alt_x[ok]).max(initial=0) <= LSB_FL_M / 2 + 1e-9
