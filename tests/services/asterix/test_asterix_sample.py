"""The public 7-radar sample (../shared/data/cat_034_048.pcap) against the independent
decoding in cat_034_048.decoded.txt (CroatiaControlLtd/asterix's decoder output).

The reference text is parsed here; values are compared as raw ASTERIX integers, so the
test checks the conversions (NM → m, deg → rad, FL → m, time of day + date → ns) too.
"""

from __future__ import annotations

import datetime as dt
import itertools
import math
import re
from collections import Counter
from pathlib import Path

import pytest
from service_support import SHARED_DATA
from skyfuse.services.asterix import read_asterix

DATA = SHARED_DATA
PCAP = DATA / "cat_034_048.pcap"
DECODED = DATA / "cat_034_048.decoded.txt"

pytestmark = pytest.mark.skipif(
    not (PCAP.exists() and DECODED.exists()), reason="../shared/data sample files absent"
)

_FIELD = re.compile(r"^\t([^:]+): (-?\w+)")


def parse_reference(path: Path) -> list[dict]:
    """Records of the decoded text: {'cat', item -> {field -> raw token}}."""
    records: list[dict] = []
    cat = None
    rec: dict | None = None
    item = None
    for line in path.read_text().splitlines():
        if line.startswith("Category: "):
            cat = int(line.split(":")[1])
        elif line.startswith("Data Record"):
            rec = {"cat": cat}
            records.append(rec)
            item = None
        elif line.startswith("Item ") and rec is not None:
            item = line.split()[1]
            rec[item] = {}
        elif item is not None and rec is not None:
            m = _FIELD.match(line)
            if m:
                rec[item][m.group(1).strip()] = m.group(2)
    return records


def reference_plots(records: list[dict]) -> Counter:
    """(sac, sic, tod_raw, rho_raw, theta_raw, fl_raw|None, address|None, mode3a|None)."""
    out: Counter = Counter()
    for r in records:
        if r["cat"] != 48 or "040" not in r or r["020"]["TYP"] == "0":
            continue
        fl = None
        if "090" in r and r["090"]["V"] == "0" and r["090"]["G"] == "0":
            fl = int(r["090"]["FlightLevel"])
        code = None
        if "070" in r and r["070"]["V"] == "0" and r["070"]["G"] == "0":
            code = int(r["070"]["Mode-3/A reply code"], 8)
        addr = int(r["220"]["AircraftAddress"], 16) if "220" in r else None
        out[
            (
                int(r["010"]["System Area Code"]),
                int(r["010"]["System Identification Code"]),
                int(r["140"]["Time Of Day"]),
                int(r["040"]["RHO"]),
                int(r["040"]["THETA"]),
                fl,
                addr,
                code,
            )
        ] += 1
    return out


def our_plots(result) -> Counter:
    out: Counter = Counter()
    day_ns = 86_400 * 10**9
    for b in result.batches:
        sac, sic = (int(x) for x in b.radar_id.split("-"))
        for i in range(len(b)):
            tod = (b.time[i] % day_ns) * 128 / 1e9
            rho = b.range[i] / 1852.0 * 256.0
            theta = math.degrees(b.azimuth[i]) * 65536.0 / 360.0
            alt = b.altitude[i]
            fl = None if alt is None else alt / 0.3048 / 100.0 * 4.0
            for v in (tod, rho, theta) + ((fl,) if fl is not None else ()):
                assert abs(v - round(v)) < 1e-6, "a value is not on its ASTERIX LSB grid"
            out[
                (
                    sac,
                    sic,
                    round(tod),
                    round(rho),
                    round(theta),
                    None if fl is None else round(fl),
                    b.mode_s[i],
                    b.mode_3a[i],
                )
            ] += 1
    return out


@pytest.fixture(scope="module")
def reference():
    return parse_reference(DECODED)


def test_reference_parser_sees_the_documented_content(reference):
    cats = Counter(r["cat"] for r in reference)
    assert cats == {48: 128, 34: 34}


def test_all_plots_match_the_independent_decoding(reference):
    result = read_asterix(PCAP, dedup=False)
    ref = reference_plots(reference)
    ours = our_plots(result)
    assert sum(ref.values()) == 126  # 128 CAT048 records, 2 of them TYP 0 "no detection"
    assert ours == ref
    assert result.stats["cat048_no_detection"] == 2
    assert set(result.radars) == {"25-11", "25-12", "25-13", "25-14", "25-201", "25-204", "25-205"}


def test_duplicate_feed_lines_are_dropped_once(reference):
    """The capture holds each datagram twice (two multicast groups = redundant lines)."""
    once = read_asterix(PCAP)
    twice = read_asterix(PCAP, dedup=False)
    assert once.stats["duplicate_records"] == 81  # 64 CAT048 + 17 CAT034
    assert 2 * once.n_plots == twice.n_plots == 126
    assert {k: 2 * v for k, v in our_plots(once).items()} == our_plots(twice)


def test_amplitude_and_plot_type_follow_the_reference(reference):
    result = read_asterix(PCAP, dedup=False)
    ref = Counter()
    for r in reference:
        if r["cat"] == 48 and "040" in r and r["020"]["TYP"] != "0":
            amp = r.get("130", {}).get("SSR-Reply amplitude")
            amp = None if amp is None else int(amp)
            tod, rho = int(r["140"]["Time Of Day"]), int(r["040"]["RHO"])
            ref[(tod, rho, int(r["020"]["TYP"]), amp)] += 1
    ours = Counter()
    for b, types in zip(result.batches, result.plot_types):
        for i in range(len(b)):
            tod = round((b.time[i] % (86_400 * 10**9)) * 128 / 1e9)
            amp = b.amplitude[i]
            amp = None if amp is None else round(amp)
            ours[(tod, round(b.range[i] / 1852 * 256), types[i], amp)] += 1
    assert ours == ref


def test_times_take_the_date_from_the_capture():
    result = read_asterix(PCAP)
    first = min(t for b in result.batches for t in b.time)
    # reference: first plot time of day 3501389/128 s; capture date 2016-05-05 (UTC)
    midnight = int(dt.datetime(2016, 5, 5, tzinfo=dt.UTC).timestamp())
    assert first == midnight * 10**9 + 3501389 * 10**9 // 128
    forced = read_asterix(PCAP, date=dt.date(2020, 1, 2))
    shift = dt.datetime(2020, 1, 2, tzinfo=dt.UTC) - dt.datetime(2016, 5, 5, tzinfo=dt.UTC)
    shift_ns = round(shift.total_seconds()) * 10**9
    assert min(t for b in forced.batches for t in b.time) == first + shift_ns


def test_service_messages_give_boundaries_and_scan_period(reference):
    result = read_asterix(PCAP, dedup=False)
    ref_crossings = sum(1 for r in reference if r["cat"] == 34 and r["000"]["Message Type"] == "2")
    ref_north = sum(1 for r in reference if r["cat"] == 34 and r["000"]["Message Type"] == "1")
    assert result.stats["cat034_sector_crossings"] == ref_crossings == 32
    assert result.stats["cat034_north_markers"] == ref_north == 2
    period = [int(r["041"]["Antenna rotation speed"]) / 128 for r in reference if "041" in r]
    assert result.scan_period_source["25-12"] == "cat034"
    assert result.sites["25-12"].scan_period == pytest.approx(period[0])
    for b in result.batches:  # every plot lies in its batch's sector (2 LSB of I020 slack)
        for a in b.azimuth or []:
            assert (a - b.sector_start) % (2 * math.pi) <= b.sector_width + 2 * math.pi / 256


def test_batches_are_valid_and_ordered():
    result = read_asterix(PCAP)
    assert [b.time_end for b in result.batches] == sorted(b.time_end for b in result.batches)
    per_radar: dict[str, list] = {}
    for b in result.batches:
        per_radar.setdefault(b.radar_id, []).append(b)
    for batches in per_radar.values():
        assert [b.seq for b in batches] == list(range(len(batches)))
        assert all(b1.time_end <= b2.time_end for b1, b2 in itertools.pairwise(batches))
    assert sum(result.radars.values()) == result.n_plots == 63


def test_stream_decoder_on_the_sample_datagrams():
    """Datagram by datagram, sectors emitted at once (max_plot_delay = 0): the same
    plots come out, and the plots that three radars deliver after their sector
    message are counted as late instead of being lost."""
    from skyfuse.services.asterix import AsterixStreamDecoder
    from skyfuse.services.asterix.pcap import iter_file_datagrams

    dec = AsterixStreamDecoder()
    batches = []
    for dgram in iter_file_datagrams(PCAP, dec.stats):
        batches += dec.feed(dgram.payload, dgram.time_ns)
    batches += dec.flush()
    assert sum(len(b) for b in batches) == 63
    assert dec.stats["late_plots"] > 0
    assert set(dec.radars) == set(read_asterix(PCAP).radars)
