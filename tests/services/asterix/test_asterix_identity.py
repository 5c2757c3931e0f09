"""Secondary-surveillance data of CAT048 plots: Mode-3/A and flight level with their
flags, SPI, flight status, callsign and the Mode S BDS registers (I250).

References: pyModeS's own documented examples (message hex → values, from its test
suite and README), the independent decoding of the 7-radar sample
(cat_034_048.decoded.txt, CroatiaControl's decoder) and the same independent decoder
(asterix-decoder, in a virtualenv of its own) on the Barcelona recording."""

from __future__ import annotations

import datetime as dt
import math
import re
import sys
from collections import Counter, defaultdict

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from service_support import SHARED_DATA
from skyfuse.schemas import PlotBatch
from skyfuse.schemas.identity import DOWNLINKED_BY_NAME, FT_PER_MIN, KT
from skyfuse.schemas.plots import FLAG_COLUMNS as FLAGS
from skyfuse.services.asterix import AsterixPlotWriter, AsterixStreamDecoder, bds, read_asterix
from skyfuse.services.asterix.reader import SECONDARY_COLUMNS

PCAP = SHARED_DATA / "cat_034_048.pcap"
DECODED = SHARED_DATA / "cat_034_048.decoded.txt"
BCN = SHARED_DATA / "bcn_20230502_0800_0815_cat048.ast"


def mb_of(message: str) -> int:
    """The 56-bit MB field of a 112-bit Comm-B message (bits 33-88)."""
    return (int(message, 16) >> 24) & ((1 << 56) - 1)


# pyModeS's documented examples (tests/test_bds_commb.py, tests/test_commb.py, README):
# message → values in pyModeS's units (ft, deg, kt, deg/s, ft/min).
BDS40 = "A000029C85E42F313000007047D3"  # MCP 3008 ft, FMS 3008 ft
BDS50 = "A000139381951536E024D4CCF6B5"  # roll 2.1°, track 114.258°, GS 438, 0.125°/s, TAS 424
BDS60 = "A00004128F39F91A7E27C46ADC21"  # hdg 42.715°, IAS 252, M 0.42, -1920/-1920 ft/min
BDS20 = "A000083E202CC371C31DE0AA1CCF"  # KLM1017


def test_pymodes_documented_examples_with_and_without_the_register_number():
    for code in (0x40, 0):  # numbered by the radar (I250 BDS1/BDS2), or inferred
        v, counts = bds.decode_registers([(mb_of(BDS40), code)], 0x4243D0)
        assert v == {"selected_altitude_mcp": 30.08, "selected_altitude_fms": 30.08}
        assert counts == ["bds_decoded_4_0" if code else "bds_inferred_4_0"]
    for code in (0x50, 0):
        v, _ = bds.decode_registers([(mb_of(BDS50), code)])
        assert math.degrees(v["roll_angle"]) == pytest.approx(2.1, abs=0.05)
        assert math.degrees(v["true_track"]) == pytest.approx(114.258, abs=0.001)
        assert v["ground_speed"] == pytest.approx(438 * 1852 / 3600)
        assert math.degrees(v["track_angle_rate"]) == pytest.approx(0.125)
        assert v["true_airspeed"] == pytest.approx(424 * 1852 / 3600)
    for code in (0x60, 0):
        v, _ = bds.decode_registers([(mb_of(BDS60), code)])
        assert math.degrees(v["magnetic_heading"]) == pytest.approx(42.715, abs=0.001)
        assert v["indicated_airspeed"] == pytest.approx(252 * 1852 / 3600)
        assert v["mach"] == pytest.approx(0.42)
        assert v["baro_vertical_rate"] == pytest.approx(-1920 * 0.3048 / 60)
        assert v["inertial_vertical_rate"] == pytest.approx(-1920 * 0.3048 / 60)
    assert bds.decode_registers([(mb_of(BDS20), 0x20)])[0] == {"callsign": "KLM1017"}
    # a register the plot does not carry, and one that nothing recognises
    assert bds.decode_registers([(0x10030A80FD0000, 0x10)]) == ({}, ["bds_register_not_used"])
    assert bds.decode_registers([(0, 0)]) == ({}, ["bds_not_recognised"])


# BDS 4,0: the selected altitudes are bits 1-26; the barometric pressure setting and the
# mode bits that follow are not carried. BDS 5,0 and 6,0: every bit is a carried field.
CARRIED = {"4,0": ((1 << 26) - 1) << 30, "5,0": (1 << 56) - 1, "6,0": (1 << 56) - 1}


@pytest.mark.parametrize(("message", "name"), [(BDS40, "4,0"), (BDS50, "5,0"), (BDS60, "6,0")])
def test_encoding_the_documented_values_gives_the_documented_bits(message, name):
    values, _ = bds.decode_registers([(mb_of(message), int(name[0]) << 4)])
    assert bds.encode_register(name, values) == mb_of(message) & CARRIED[name]


_PARAMS = st.fixed_dictionaries(
    {},
    optional={
        "selected_altitude_mcp": st.floats(0, 655.2),
        "selected_altitude_fms": st.floats(0, 655.2),
        "roll_angle": st.floats(-1.5, 1.5),
        "true_track": st.floats(0, 2 * math.pi, exclude_max=True),
        "ground_speed": st.floats(0, 1050),
        "track_angle_rate": st.floats(-0.27, 0.27),
        "true_airspeed": st.floats(0, 1050),
        "magnetic_heading": st.floats(0, 2 * math.pi, exclude_max=True),
        "indicated_airspeed": st.floats(0, 525),
        "mach": st.floats(0, 4.09),
        "baro_vertical_rate": st.floats(-83, 83),
        "inertial_vertical_rate": st.floats(-83, 83),
    },
)
_LSB = {  # the LSB of each register field, in skyfuse units
    "selected_altitude_mcp": 0.16, "selected_altitude_fms": 0.16,
    "roll_angle": math.radians(45 / 256), "true_track": math.radians(90 / 512),
    "ground_speed": 2 * KT, "track_angle_rate": math.radians(8 / 256), "true_airspeed": 2 * KT,
    "magnetic_heading": math.radians(90 / 512), "indicated_airspeed": KT, "mach": 2.048 / 512,
    "baro_vertical_rate": 32 * FT_PER_MIN, "inertial_vertical_rate": 32 * FT_PER_MIN,
}  # fmt: skip


@settings(max_examples=300, deadline=None)
@given(_PARAMS)
def test_encoded_registers_decode_back_through_pymodes(values):
    registers = []
    for name in ("4,0", "5,0", "6,0"):
        mb = bds.encode_register(name, values)
        if mb is not None:
            registers.append((mb, int(name[0]) << 4))
    got, _ = bds.decode_registers(registers)
    assert set(got) == set(values)
    for key, want in values.items():
        diff = got[key] - want
        if key in ("true_track", "magnetic_heading"):
            diff = (diff + math.pi) % (2 * math.pi) - math.pi
        assert abs(diff) <= _LSB[key] / 2 + 1e-9, key
        q = DOWNLINKED_BY_NAME[key]
        assert q.lo <= got[key] and (got[key] < q.hi if q.hi_open else got[key] <= q.hi)


def test_without_pymodes_the_registers_are_counted_and_the_rest_is_read(monkeypatch):
    if not PCAP.exists():
        pytest.skip("../shared/data sample absent")
    monkeypatch.setitem(sys.modules, "pyModeS", None)  # import pyModeS → ImportError
    bds._load.cache_clear()
    try:
        assert not bds.available()
        assert bds.decode_registers([(mb_of(BDS40), 0x40)]) == (
            {}, ["bds_not_decoded_no_pymodes"])  # fmt: skip
        result = read_asterix(PCAP, dedup=False)
    finally:
        monkeypatch.undo()
        bds._load.cache_clear()
    assert bds.available()
    assert result.stats["cat048_bds_not_decoded_no_pymodes"] == 124  # every I250 register
    assert not any(k.startswith("cat048_bds_decoded") for k in result.stats)
    assert any("pyModeS is not installed" in m for m in result.messages)
    plots = [p for b in result.batches for p in zip(b.callsign or [], b.ground_speed or [])]
    # 124 plots with I240: 2 all spaces, 2 all zeros (no identification)
    assert sum(c is not None for c, _ in plots) == 120 and all(g is None for _, g in plots)


# ------------------------------------------------------------- the 7-radar sample
_I250_FIELDS = {  # decoded text field → (our column, raw LSB in pyModeS's units, angle)
    "MCP/FCU Selected Altitude": ("selected_altitude_mcp", 16 / 100, False),
    "FMS Selected Altitude": ("selected_altitude_fms", 16 / 100, False),
    "Roll Angle": ("roll_angle", math.radians(45 / 256), False),
    "True Track Angle": ("true_track", math.radians(90 / 512), True),
    "Ground Speed": ("ground_speed", 2 * KT, False),
    "Track Angle Rate": ("track_angle_rate", math.radians(8 / 256), False),
    "True Airspeed": ("true_airspeed", 2 * KT, False),
    "Magnetic Heading": ("magnetic_heading", math.radians(90 / 512), True),
    "Indicated Airspeed": ("indicated_airspeed", KT, False),
    "Mach Speed": ("mach", 2.048 / 512, False),
    "Barometric Altitude Rate": ("baro_vertical_rate", 32 * FT_PER_MIN, False),
    "Inertial Vertical Velocity": ("inertial_vertical_rate", 32 * FT_PER_MIN, False),
}
_STATUS = {"MCP/FCU Selected Altitude": "MCP Altitude Status",
           "FMS Selected Altitude": "FMS Altitude Status", "Roll Angle": "Roll Angle Status",
           "True Track Angle": "True Track Angle Status", "Ground Speed": "Ground Speed Status",
           "Track Angle Rate": "Track Angle Rate Status",
           "True Airspeed": "True Airspeed Status", "Magnetic Heading": "Heading Status",
           "Indicated Airspeed": "Indicated Airspeed Status",
           "Mach Speed": "Mach Speed Status",
           "Barometric Altitude Rate": "Barometric Altitude Rate Status",
           "Inertial Vertical Velocity": "Inertial Vertical Velocity Status"}  # fmt: skip
_LINE = re.compile(r"^\t([^:]+): (-?\w+)")


def reference_records() -> list[dict]:
    """The CAT048 records of the decoded text: plot key, identity fields and the I250
    registers (each its fields, raw integers, and its number)."""
    out, rec, item = [], None, None
    for line in DECODED.read_text().splitlines():
        if line.startswith("Category: "):
            cat = int(line.split(":")[1])
        elif line.startswith("Data Record"):
            rec = {"cat": cat, "250": []}
            out.append(rec)
            item = None
        elif line.startswith("Item ") and rec is not None:
            item = line.split()[1]
            if item == "250":
                reg: dict = {}
            else:
                rec[item] = {}
        elif item == "240" and "Characters 1-8" in line:
            rec[item]["callsign"] = line.split(": ", 1)[1].rstrip()
        elif item is not None and (m := _LINE.match(line)):
            key, val = m.group(1).strip(), m.group(2)
            if item == "250":
                reg[key] = val
                if key == "BDS register":
                    rec["250"].append(reg)
                    reg = {}
            else:
                rec[item][key] = val
    return [r for r in out if r["cat"] == 48 and "040" in r and r["020"]["TYP"] != "0"]


def _key(sac, sic, tod_raw, rho_raw, theta_raw):
    return (sac, sic, tod_raw, rho_raw, theta_raw)


def our_plots_by_key(result) -> dict:
    """Our plots (one dict of columns each) by (SAC, SIC, raw time, RHO, THETA)."""
    out = defaultdict(list)
    day_ns = 86_400 * 10**9
    for b in result.batches:
        sac, sic = (int(x) for x in b.radar_id.split("-"))
        for i in range(len(b)):
            tod = round((b.time[i] % day_ns) * 128 / 1e9)
            theta = round(math.degrees(b.azimuth[i]) * 65536 / 360)
            key = _key(sac, sic, tod, round(b.range[i] / 1852 * 256), theta)
            out[key].append({c: getattr(b, c)[i] for c in ("mode_3a", *SECONDARY_COLUMNS)})
    return out


@pytest.mark.skipif(not (PCAP.exists() and DECODED.exists()), reason="../shared/data absent")
def test_sample_identity_and_registers_match_the_independent_decoding():
    result = read_asterix(PCAP, dedup=False)
    ours = our_plots_by_key(result)
    compared = Counter()
    for r in reference_records():
        source = r["010"]
        sac, sic = int(source["System Area Code"]), int(source["System Identification Code"])
        pos = r["040"]
        key = _key(sac, sic, int(r["140"]["Time Of Day"]), int(pos["RHO"]), int(pos["THETA"]))
        (p,) = {repr(x): x for x in ours[key]}.values()  # duplicates are identical
        if "070" in r:
            assert p["mode_3a"] == int(r["070"]["Mode-3/A reply code"], 8)
            assert (p["mode_3a_not_validated"], p["mode_3a_garbled"], p["mode_3a_smoothed"]) == (
                r["070"]["V"] == "1", r["070"]["G"] == "1", r["070"]["L"] == "1")  # fmt: skip
            compared["070"] += 1
        if "090" in r:
            assert p["flight_level"] * 4 == int(r["090"]["FlightLevel"])
            compared["090"] += 1
        if "240" in r:
            assert p["callsign"] == (r["240"]["callsign"] or None)
            compared["240"] += 1
        if "230" in r:
            assert p["flight_status"] == int(r["230"]["STAT"])
            compared["230"] += 1
        assert p["spi"] == (r["020"]["SPI"] == "1")
        for reg in r["250"]:
            for field, (column, lsb, angle) in _I250_FIELDS.items():
                if field in reg and reg[_STATUS[field]] == "1":
                    raw = p[column] / lsb
                    want = int(reg[field]) % 2048 if angle else int(reg[field])
                    assert round(raw) % 2048 == want if angle else round(raw) == want, field
                    assert abs(raw - round(raw)) < 1e-6
                    compared[f"250 {reg['BDS register']}"] += 1
    assert compared["070"] == 126 and compared["240"] == 124 and compared["230"] == 124
    # fields with their status bit set: 82 BDS 4,0 (MCP, some FMS), 4 BDS 5,0, 36 BDS 6,0
    assert (compared["250 40"], compared["250 50"], compared["250 60"]) == (96, 20, 180)


# ------------------------------------------------------------ the Barcelona recording
_INDEPENDENT_I250 = {  # asterix-decoder field → our column, unit factor (ours → theirs)
    "MCP_ALT": ("selected_altitude_mcp", 100.0), "FMS_ALT": ("selected_altitude_fms", 100.0),
    "RA": ("roll_angle", 180 / math.pi), "TTA": ("true_track", 180 / math.pi),
    "GS": ("ground_speed", 1 / KT), "TAR": ("track_angle_rate", 180 / math.pi),
    "TAS": ("true_airspeed", 1 / KT), "HDG": ("magnetic_heading", 180 / math.pi),
    "IAS": ("indicated_airspeed", 1 / KT), "MACH": ("mach", 1.0),
    "BAR": ("baro_vertical_rate", 1 / FT_PER_MIN),
    "IVV": ("inertial_vertical_rate", 1 / FT_PER_MIN),
}  # fmt: skip
_STATUS_OF = {"MCP_ALT": "MCP_ALT_STATUS", "FMS_ALT": "FMS_ALT_STATUS", "RA": "RA_STATUS",
              "TTA": "TTA_STATUS", "GS": "GS_STATUS", "TAR": "TAR_STATUS", "TAS": "TAS_STATUS",
              "HDG": "HDG_STATUS", "IAS": "IAS_STAT", "MACH": "MACH_STATUS",
              "BAR": "BAR_STATUS", "IVV": "IVV_STATUS"}  # fmt: skip


@pytest.mark.skipif(not BCN.exists(), reason="../shared/data Barcelona recording absent")
def test_barcelona_secondary_data_match_an_independent_decoder(independent_decoder):
    result = read_asterix(BCN, date=dt.date(2023, 5, 2), dedup=False)
    ours = our_plots_by_key(result)
    n = Counter()
    for r in independent_decoder(BCN):
        items = ("I010", "I140", "I020", "I040", "I070", "I090", "I230", "I240")
        v = {i: {k: f["val"] for k, f in r[i].items()} for i in items if i in r}
        if v["I020"]["TYP"] == 0:  # "no detection": not a plot
            n["no detection"] += 1
            continue
        tod, pos = round(v["I140"]["ToD"] * 128), v["I040"]
        theta = round(pos["THETA"] * 65536 / 360)
        key = _key(v["I010"]["SAC"], v["I010"]["SIC"], tod, round(pos["RHO"] * 256), theta)
        (p,) = {repr(x): x for x in ours[key]}.values()
        n["records"] += 1
        if "I070" in v:
            assert f"{p['mode_3a']:04o}" == v["I070"]["Mode3A"]
            flags = (p["mode_3a_not_validated"], p["mode_3a_garbled"], p["mode_3a_smoothed"])
            assert flags == (v["I070"]["V"] == 1, v["I070"]["G"] == 1, v["I070"]["L"] == 1)
            n["I070"] += 1
        if "I090" in v:
            assert p["flight_level"] == v["I090"]["FL"]
            assert p["flight_level_not_validated"] == (v["I090"]["V"] == 1)
            n["I090"] += 1
        if "I240" in v:
            assert p["callsign"] == (v["I240"]["TId"].rstrip() or None)
            n["I240"] += 1
        if "I230" in v:
            assert p["flight_status"] == v["I230"]["STAT"]
            n["I230"] += 1
        assert p["spi"] == (v["I020"]["SPI"] == 1)
        for reg in r.get("I250", []):
            for field, (column, factor) in _INDEPENDENT_I250.items():
                if field in reg and reg[_STATUS_OF[field]]["val"] == 1:
                    theirs, mine = reg[field]["val"], p[column] * factor
                    if field in ("TTA", "HDG"):  # theirs signed, ours in [0, 360)
                        theirs %= 360.0
                    assert mine == pytest.approx(theirs, abs=1e-6), (field, key)
                    n[f"I250 {reg['BDS']['val']}"] += 1
    assert n["records"] == result.n_plots == 11_027 - n["no detection"]
    assert n["no detection"] == result.stats["cat048_no_detection"] == 46
    assert n["I070"] > 10_900 and n["I240"] > 10_500 and n["I090"] > 10_300
    assert n["I250 40"] > 9_000 and n["I250 50"] > 10_000 and n["I250 60"] > 40_000
    assert result.stats["cat048_bds_decoded_4_0"] == 9_669  # every BDS 4,0 register of it


# ------------------------------------------------------------ writer → reader
@settings(max_examples=60, deadline=None)
@given(st.data())
def test_secondary_columns_round_trip_through_cat048(data):
    n = data.draw(st.integers(1, 6))

    def column(values):
        return data.draw(st.lists(st.none() | values, min_size=n, max_size=n))

    cols = {
        "mode_3a": column(st.integers(0, 4095)),
        "mode_s": [0x4CA000 + i for i in range(n)],
        "callsign": column(st.from_regex(r"[A-Z0-9]([A-Z0-9 ]{0,6}[A-Z0-9])?", fullmatch=True)),
        "flight_level": column(st.floats(-20, 1200)),
        "flight_status": column(st.integers(0, 7)),
    }
    for flag in FLAGS:
        cols[flag] = column(st.booleans())
    params = [data.draw(_PARAMS) for _ in range(n)]
    for q in DOWNLINKED_BY_NAME:
        cols[q] = [p.get(q) for p in params]
    t0 = 1_683_014_400_000_000_000
    sent = PlotBatch(
        radar_id="20-129",
        scan=0,
        seq=0,
        sector_start=0.0,
        sector_width=math.pi / 8,
        time_start=t0,
        time_end=t0 + 250_000_000,
        time=[t0 + 10_000_000 * (i + 1) for i in range(n)],
        range=[10_000.0 * (i + 1) for i in range(n)],
        azimuth=[0.01 * (i + 1) for i in range(n)],
        **cols,
    )
    got = AsterixPlotWriter().encode([sent])
    dec = AsterixStreamDecoder(date=dt.date(2023, 5, 2))
    (back,) = [b for b in dec.feed(got) + dec.flush() if len(b)]
    assert back.mode_3a == sent.mode_3a and back.callsign == sent.callsign
    assert back.flight_status == sent.flight_status
    for flag in FLAGS:
        # a flag on a plot without its code is not carried (nothing to flag)
        carried = next((c for c in ("mode_3a", "flight_level") if flag.startswith(c)), None)
        want = [
            bool(f) and (carried is None or getattr(sent, carried)[i] is not None)
            for i, f in enumerate(getattr(sent, flag))
        ]
        assert getattr(back, flag) == want, flag
    for a, b in zip(sent.flight_level, back.flight_level):
        assert (a is None) == (b is None) and (a is None or abs(a - b) <= 0.125)
    for key, lsb in _LSB.items():
        for a, b in zip(getattr(sent, key), getattr(back, key)):
            assert (a is None) == (b is None), key
            if a is not None:
                diff = b - a
                if key in ("true_track", "magnetic_heading"):
                    diff = (diff + math.pi) % (2 * math.pi) - math.pi
                assert abs(diff) <= lsb / 2 + 1e-9, key
