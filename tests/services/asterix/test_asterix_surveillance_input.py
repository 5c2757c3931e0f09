"""CAT010/CAT020/CAT021 input handling: the fast path against libasterix (differential,
real and random records), CAT021 edition selection, bad input counted and never raised,
and the ADS-B quality tables against the standards' values."""

from __future__ import annotations

import math

import asterix.generated as gen
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import stats as sps
from service_support import SHARED_DATA
from skyfuse.schemas import adsb_quality
from skyfuse.services.asterix import AsterixStreamDecoder, cat010, cat020, cat021
from skyfuse.services.asterix.pcap import Datagram
from skyfuse.services.asterix.records import RecordError, iter_records
from skyfuse.services.asterix.surveillance import columns, read_reports
from skyfuse.services.asterix.writer import datablock

MLAT = SHARED_DATA / "lebl_20160510_2200_2215_mlat.ast"
SMR = SHARED_DATA / "lebl_20160510_2200_2215_smr.ast"
ADSB = SHARED_DATA / "lebl_20160510_2200_2215_adsb.ast"
NM = 1852.0


def lib_first(spec, decode, data: bytes):
    for rec in iter_records(spec, data):
        if isinstance(rec, RecordError):
            return None
        return decode(rec), len(rec.unparse().to_bytes())
    return None


def agree(spec, fast, decode, data: bytes) -> None:
    """The fast path and libasterix decode the first record of ``data`` alike (or both
    refuse it)."""
    got = fast(data, 0)
    lib = lib_first(spec, decode, data)
    assert (got is None) == (lib is None), (data.hex(), got, lib)
    if got is not None:
        assert got == lib, data.hex()


CASES = {
    10: (cat010.SPEC, cat010.decode_fast, cat010.decode_record),
    20: (cat020.SPEC, cat020.decode_fast, cat020.decode_record),
    21: (
        cat021.EDITIONS["0.23"],
        lambda d, p: cat021.decode_fast(d, p, "0.23"),
        lambda r: cat021.decode_record(r, "0.23"),
    ),
    212: (
        cat021.EDITIONS["2.6"],
        lambda d, p: cat021.decode_fast(d, p, "2.6"),
        lambda r: cat021.decode_record(r, "2.6"),
    ),
}


@pytest.mark.parametrize("path, case", [(MLAT, 10), (SMR, 10), (ADSB, 21)])
def test_real_records_fast_path_agrees_with_libasterix(path, case):
    if not path.exists():
        pytest.skip(f"{path} absent")
    data = path.read_bytes()
    pos, n = 0, 0
    while pos < len(data) and n < 600:
        length = int.from_bytes(data[pos + 1 : pos + 3], "big")
        agree(*CASES[case], data[pos + 3 : pos + length])
        pos, n = pos + length, n + 1
    assert n == 600


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=st.sampled_from(sorted(CASES)), data=st.binary(min_size=1, max_size=60))
def test_random_bytes_fast_path_agrees_with_libasterix(case, data):
    agree(*CASES[case], data)


def test_stream_counts_bad_cat010_input_and_keeps_the_good_records():
    good = cat010_block(3)
    body = good[3:-4]  # the third record cut short, block length fixed
    bad = bytes([10]) + (len(body) + 3).to_bytes(2, "big") + body
    garbage = bytes([10, 0, 9]) + b"\xff" * 6  # an FSPEC that never ends
    dec = AsterixStreamDecoder(dedup=False)
    dec.feed_with_types(Datagram(good + bad + garbage + cat010_block(2), 0, raw_stream=True))
    reports = dec.take_reports()
    assert len(reports) == 3 + 2 + 2
    assert dec.stats["cat010_malformed_record"] == 2
    assert dec.take_reports() == []


def cat010_block(n: int, tod: float = 3600.0) -> bytes:
    recs = []
    for i in range(n):
        rec = cat010.SPEC.cv_record.create(
            {
                "010": (("SAC", 0), ("SIC", 107)),
                "000": 1,
                "020": ((1, 0, 0, 0, 0, None),),
                "140": round((tod + i) * 128),
                "042": (("X", 100 + i), ("Y", -200)),
                "161": (0, ("TRK", i)),
            }
        )
        recs.append(rec.unparse().to_bytes())
    return datablock(10, recs)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    cat=st.sampled_from([10, 20, 21]),
    noise=st.binary(min_size=0, max_size=80),
    cut=st.integers(0, 40),
)
def test_random_blocks_never_raise(cat, noise, cut):
    good = cat010_block(2)
    body = (good[3:] + noise)[: max(1, len(good) - 3 + len(noise) - cut)]
    block = bytes([cat]) + (len(body) + 3).to_bytes(2, "big") + body
    dec = AsterixStreamDecoder(dedup=False)
    dec.feed_with_types(Datagram(block + good, 0))
    assert len(dec.take_reports()) >= 2  # the good block after it is never lost


def test_a_report_sink_takes_every_report_and_the_buffer_is_bounded(monkeypatch):
    from skyfuse.services.asterix import reader

    sink: list = []
    dec = AsterixStreamDecoder(dedup=False, report_sink=sink.append)
    dec.feed_with_types(Datagram(cat010_block(5), 0))
    assert len(sink) == 5 and dec.take_reports() == []
    monkeypatch.setattr(reader, "MAX_PENDING_REPORTS", 3)
    dec = AsterixStreamDecoder(dedup=False)
    dec.feed_with_types(Datagram(cat010_block(5), 0))
    kept = dec.take_reports()
    assert [r.track_number for r in kept] == [2, 3, 4] and dec.stats["reports_dropped"] == 2


def test_cat021_edition_is_detected_per_source_and_can_be_forced():
    if not ADSB.exists():
        pytest.skip(f"{ADSB} absent")
    data = ADSB.read_bytes()
    first = data[: int.from_bytes(data[1:3], "big")]
    rec = gen.Cat_021_2_6.cv_record.create(
        {
            "010": (("SAC", 9), ("SIC", 9)),
            "040": ((0, 0, 0, 0, None),),
            "071": 79_202 * 128,
            "130": (("LAT", 1_950_000), ("LON", 100_000)),
            "080": 0x4CA5F7,
        }
    )
    v26 = gen.Cat_021_2_6.create([rec]).unparse().to_bytes()
    dec = AsterixStreamDecoder(dedup=False)
    dec.feed_with_types(Datagram(first + v26 + first + v26, 0))
    got = dec.take_reports()
    assert [(r.sic, r.edition) for r in got] == [(107, "0.23"), (9, "2.7")] * 2
    assert dec.stats["cat021_edition_changes"] == 0
    forced = AsterixStreamDecoder(dedup=False, cat021_edition="2.6")
    forced.feed_with_types(Datagram(first + v26, 0))
    assert [r.edition for r in forced.take_reports()] == ["2.6"]
    assert (
        sum(v for k, v in forced.stats.items() if k.startswith("cat021_no"))
        + forced.stats["cat021_malformed_record"]
        >= 1
        or forced.stats["cat021_bad_position"] >= 1
    )
    with pytest.raises(ValueError, match="cat021_edition"):
        AsterixStreamDecoder(cat021_edition="3.0")


def test_lebl_files_decode_without_rejections():
    for path, kinds in ((MLAT, {"Cat010Report", "Cat010Status"}), (ADSB, {"Cat021Report"})):
        if not path.exists():
            pytest.skip(f"{path} absent")
        reports, stats, _ = read_reports(path)
        assert {type(r).__name__ for r in reports} == kinds
        assert not [k for k in stats if "malformed" in k or "no_" in k], stats
        assert all(r.time_ns is not None for r in reports)
    cols = columns(reports, ("time_ns", "lat", "address", "callsign", "flight_level"))
    assert cols["time_ns"].dtype == np.int64 and cols["callsign"].dtype == object
    assert np.all(np.diff(cols["time_ns"]) >= 0)


# ------------------------------------------------------------- ADS-B quality tables
def test_nacp_table_is_the_standards_epu():
    """NACp → EPU (95 %), RTCA DO-260A/DO-260B, in the units the standard states."""
    standard = {11: "3 m", 10: "10 m", 9: "30 m", 8: "0.05 NM", 7: "0.1 NM", 6: "0.3 NM"}
    standard |= {5: "0.5 NM", 4: "1 NM", 3: "2 NM", 2: "4 NM", 1: "10 NM"}
    for nacp, text in standard.items():
        value, unit = text.split()
        assert adsb_quality.NACP_EPU_M[nacp] == pytest.approx(
            float(value) * (NM if unit == "NM" else 1)
        )
    assert (
        adsb_quality.position_sigma_nacp(0) is None and adsb_quality.position_sigma_nacp(12) is None
    )


def test_nucp_table_is_the_standards_hpl_and_containment_radius():
    """NUCp → (HPL, 95 % containment radius μ), RTCA DO-260."""
    standard = {9: ("7.5 m", "3 m"), 8: ("25 m", "10 m"), 7: ("0.1 NM", "0.05 NM")}
    standard |= {6: ("0.2 NM", "0.1 NM"), 5: ("0.5 NM", "0.25 NM"), 4: ("1 NM", "0.5 NM")}
    standard |= {3: ("2 NM", "1 NM"), 2: ("10 NM", "5 NM"), 1: ("20 NM", "10 NM")}

    def metres(text: str) -> float:
        value, unit = text.split()
        return float(value) * (NM if unit == "NM" else 1.0)

    for nucp, (hpl, mu) in standard.items():
        assert adsb_quality.NUCP_HPL_M[nucp] == pytest.approx(metres(hpl))
        assert adsb_quality.NUCP_R95_M[nucp] == pytest.approx(metres(mu))
    assert adsb_quality.position_sigma_nucp(0) is None
    assert adsb_quality.NACV_R95_MS == {1: 10.0, 2: 3.0, 3: 1.0, 4: 0.3}


def test_sigma_gives_a_95_percent_circle():
    """σ = R95 / √(−2 ln 0.05): the Rayleigh 95 % quantile (scipy) and a Monte Carlo
    count of 2-D Gaussian errors inside the bound."""
    assert adsb_quality.RAYLEIGH_95 == pytest.approx(sps.rayleigh.ppf(0.95), rel=1e-12)
    sigma = adsb_quality.position_sigma_nacp(9)
    err = np.random.default_rng(1).normal(0.0, sigma, size=(400_000, 2))
    inside = np.mean(np.hypot(err[:, 0], err[:, 1]) <= 30.0)
    assert inside == pytest.approx(0.95, abs=0.002)
    assert adsb_quality.velocity_sigma(2) == pytest.approx(3.0 / math.sqrt(-2 * math.log(0.05)))
