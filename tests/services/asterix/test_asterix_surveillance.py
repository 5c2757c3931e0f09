"""CAT010, CAT020 and CAT021 decoding checked against an independent decoder
(asterix-decoder, CroatiaControl's C++ decoder with its own XML definitions, run in its
own virtualenv by ``service_support.independent_asterix_decode``): real LEBL records
field by field (first, middle, last, every message type, records holding each item),
and records built with libasterix's encoder for the editions without a recording."""

from __future__ import annotations

import math
import os
from collections import Counter
from pathlib import Path

import asterix.generated as gen
import pytest
from service_support import SHARED_DATA
from skyfuse.services.asterix import cat010, cat020, cat021
from skyfuse.services.asterix.pcap import iter_file_datagrams, split_datablocks

CAT010_FILES = (
    "lebl_20160510_2200_2215_mlat.ast",
    "lebl_20160510_2200_2215_smr.ast",
    "lebl_20201002_0800_0815_mlat.ast",
    "lebl_20201002_0800_0815_smr.ast",
)
ADSB_FILE = "lebl_20160510_2200_2215_adsb.ast"
CAT010_ITEMS = ("040", "041", "042", "060", "090", "091", "200", "202", "210", "245", "270")
CAT010_ITEMS += ("500", "550")


def blocks_of(path: Path) -> list[bytes]:
    """Whole data blocks (header included) of a raw file."""
    stats: Counter = Counter()
    out = []
    for dgram in iter_file_datagrams(path, stats):
        for cat, data in split_datablocks(dgram.payload, stats, raw_stream=True):
            out.append(bytes([cat]) + (len(data) + 3).to_bytes(2, "big") + data)
    return out


def pick(blocks: list[bytes], split) -> list[int]:
    """Block indices to check: first, middle, last, 20 evenly spaced, the first three of
    each message type and the first three holding each item of interest."""
    chosen = {0, len(blocks) // 2, len(blocks) - 1, *range(0, len(blocks), len(blocks) // 20)}
    seen: Counter = Counter()
    for i, blk in enumerate(blocks):
        items = split(blk[3:])
        for key in [f"type{blk[3:][0]}"] + [f"I{k}" for k in CAT010_ITEMS if k in items]:
            if seen[key] < 3:
                seen[key] += 1
                chosen.add(i)
    return sorted(chosen)


def val(ref: dict, item: str, field: str):
    return ref[item][field]["val"]


def opt(ref: dict, item: str, field: str):
    """A field's value, or None when the item or the field (an absent extent) is not there."""
    return ref.get(item, {}).get(field, {}).get("val")


def close(a: float | None, b: float, tol: float = 1e-6) -> bool:
    return a is not None and math.isclose(a, b, rel_tol=tol, abs_tol=tol)


def check_cat010(ours, ref: dict) -> None:
    assert (ours.sac, ours.sic) == (val(ref, "I010", "SAC"), val(ref, "I010", "SIC"))
    assert ours.tod == val(ref, "I140", "ToD")
    if isinstance(ours, cat010.Cat010Status):
        assert ours.message_type == val(ref, "I000", "MsgTyp")
        if "I550" in ref:
            assert ours.nogo == val(ref, "I550", "NOGO")
            assert ours.overload == bool(val(ref, "I550", "OVL"))
            assert ours.time_source_invalid == bool(val(ref, "I550", "TSV"))
        return
    assert val(ref, "I000", "MsgTyp") == 1
    i020 = ref.get("I020", {})
    if i020:
        assert ours.typ == i020["TYP"]["val"] and ours.ground == bool(i020["GBS"]["val"])
        if "SIM" in i020:
            assert ours.sim == bool(i020["SIM"]["val"]) and ours.tst == bool(i020["TST"]["val"])
            assert ours.target_type == i020["TOT"]["val"]
    check_cat010_position(ours, ref)
    check_cat010_track(ours, ref)


def check_cat010_position(ours, ref: dict) -> None:
    if "I040" in ref:
        assert ours.rho_m == val(ref, "I040", "RHO")
        assert close(ours.theta_deg, val(ref, "I040", "Theta"))
    else:
        assert ours.rho_m is None
    if "I042" in ref:
        assert (ours.x_m, ours.y_m) == (val(ref, "I042", "X"), val(ref, "I042", "Y"))
    else:
        assert ours.x_m is None
    if "I041" in ref:
        assert close(ours.lat, val(ref, "I041", "Lat"), 1e-9)
    if "I200" in ref:
        assert close(ours.ground_speed_ms, val(ref, "I200", "GS") * 1852.0)
        assert close(ours.track_angle_deg, val(ref, "I200", "TA"))
    if "I202" in ref:
        assert (ours.vx_ms, ours.vy_ms) == (val(ref, "I202", "Vx"), val(ref, "I202", "Vy"))
    else:
        assert ours.vx_ms is None
    if "I210" in ref:
        assert (ours.ax, ours.ay) == (val(ref, "I210", "Ax"), val(ref, "I210", "Ay"))
    if "I500" in ref:
        assert ours.sigma_x_m == val(ref, "I500", "Qx")
        assert ours.sigma_y_m == val(ref, "I500", "Qy")
        assert ours.cov_xy_m2 == val(ref, "I500", "Qxy")
    if "I270" in ref:
        assert ours.length_m == val(ref, "I270", "Length")
        if "Ori" in ref["I270"]:  # CroatiaControl's LSB is 2.81° (360/128 = 2.8125)
            assert round(ours.orientation_deg / 2.8125) == round(val(ref, "I270", "Ori") / 2.81)
        if "Width" in ref["I270"]:
            assert ours.width_m == val(ref, "I270", "Width")


def check_cat010_track(ours, ref: dict) -> None:
    if "I161" in ref:
        assert ours.track_number == val(ref, "I161", "TrkNb")
    if "I170" in ref:
        assert ours.confirmed == (val(ref, "I170", "CNF") == 0)
        assert ours.last == bool(val(ref, "I170", "TRE"))
        assert ours.coasted == val(ref, "I170", "CST")
    if "I220" in ref:
        assert ours.mode_s == int(val(ref, "I220", "TAddr"), 16)
    else:
        assert ours.mode_s is None
    if "I060" in ref:
        valid = val(ref, "I060", "V") == 0 and val(ref, "I060", "G") == 0
        expected = int(val(ref, "I060", "Mod3A"), 8) if valid else None
        assert ours.mode_3a == expected
    if "I245" in ref:
        assert (ours.callsign or "") == val(ref, "I245", "TId").rstrip(" ")
    if "I090" in ref:
        valid = val(ref, "I090", "V") == 0 and val(ref, "I090", "G") == 0
        assert ours.flight_level == (val(ref, "I090", "FL") if valid else None)
    else:
        assert ours.flight_level is None
    if "I091" in ref:
        assert close(ours.height_m, val(ref, "I091", "MHeight") * 0.3048)


def split_items(data: bytes) -> dict:
    from skyfuse.services.asterix.layout import split_record

    split = split_record(data, 0, cat010.LAYOUT)
    return {} if isinstance(split, str) else split[1]


@pytest.mark.parametrize("name", CAT010_FILES)
def test_cat010_records_match_the_independent_decoder(name: str, independent_decoder):
    path = SHARED_DATA / name
    if not path.exists():
        pytest.skip(f"{path} absent")
    blocks = blocks_of(path)
    chosen = pick(blocks, split_items)
    refs = independent_decoder(b"".join(blocks[i] for i in chosen))
    assert len(refs) == len(chosen)
    kinds: Counter = Counter()
    for i, ref in zip(chosen, refs, strict=True):
        ours, end = cat010.decode_fast(blocks[i][3:], 0)
        assert end == len(blocks[i]) - 3
        check_cat010(ours, ref)
        kinds[type(ours).__name__] += 1
    assert kinds["Cat010Report"] >= 10 and kinds["Cat010Status"] >= 3


def test_cat010_velocity_lsb_is_a_quarter_metre_per_second():
    """|(VX, VY)| of I010/202 equals I010/200's ground speed with the specification's
    0.25 m/s (libasterix 0.36 declares 1/16 m/s, which would make it 4× too slow)."""
    path = SHARED_DATA / CAT010_FILES[0]
    if not path.exists():
        pytest.skip(f"{path} absent")
    ratios = []
    for blk in blocks_of(path)[:3000]:
        r, _ = cat010.decode_fast(blk[3:], 0)
        if isinstance(r, cat010.Cat010Report) and r.vx_ms is not None and r.ground_speed_ms > 5:
            ratios.append(math.hypot(r.vx_ms, r.vy_ms) / r.ground_speed_ms)
    ratios.sort()
    assert len(ratios) > 100 and abs(ratios[len(ratios) // 2] - 1.0) < 0.02


def cat021_26_record(**over) -> bytes:
    """One CAT021 edition 2.6 record with every item the decoder reads (raw values)."""
    items = {
        "010": (("SAC", 3), ("SIC", 4)),
        "040": ((1, 0, 0, 1, None), (0, 1, 0, 0, 0, 0, None)),
        "161": (0, ("TRNUM", 123)),
        "071": 4_500_000,
        "073": 4_500_010,
        "074": ((1, ("TOMRP", 2**29))),
        "130": (("LAT", 1_950_000), ("LON", -100_000)),
        "131": (("LAT", 499_000_000), ("LON", -25_000_000)),
        "080": 0xABCDEF,
        "090": ((2, 7, None), (0, 3, 9, None)),
        "210": (0, 0, 2, 2),
        "070": (0, ("MODE3A", 0o1234)),
        "145": 1000,
        "140": -20,
        "157": (0, ("GVR", 0x7F00)),
        "160": (("RE", 0), ("GS", 4000), ("TA", 30000)),
        "170": 0x0C1532C60820,
        "020": 3,
    }
    items.update(over)
    rec = gen.Cat_021_2_6.cv_record.create({k: v for k, v in items.items() if v is not None})
    return gen.Cat_021_2_6.create([rec]).unparse().to_bytes()


def check_cat021(ours: cat021.Cat021Report, ref: dict, v2: bool) -> None:
    assert (ours.sac, ours.sic) == (val(ref, "I010", "SAC"), val(ref, "I010", "SIC"))
    assert ours.address == int(val(ref, "I080", "TAddr"), 16)
    assert ours.ground == bool(opt(ref, "I040", "GBS"))
    assert ours.address_type == val(ref, "I040", "ATP")
    pos = ref["I131"] if "I131" in ref else ref["I130"]
    assert close(ours.lat, pos["Lat"]["val"], 1e-7) and close(ours.lon, pos["Lon"]["val"], 1e-7)
    if "I145" in ref:
        assert ours.flight_level == val(ref, "I145", "FL")
    if "I170" in ref:
        assert (ours.callsign or "") == val(ref, "I170", "TId").rstrip(" ")
    if "I157" in ref:
        rate = ref["I157"]["GVR"]["val"] * 0.3048 / 60.0
        assert close(ours.vertical_rate_ms, rate)
    if v2:
        assert ours.tod == val(ref, "I071", "time_applicability_position")
        assert ours.nac_v == val(ref, "I090", "NUCr_or_NACv")
        assert ours.nacp == opt(ref, "I090", "NACp") and ours.sil == opt(ref, "I090", "SIL")
        assert ours.mops_version == opt(ref, "I210", "VN")
        assert ours.track_number == val(ref, "I161", "TrackN")
        assert ours.mode_3a == int(val(ref, "I070", "Mode3A"), 8)
        assert close(ours.ground_speed_ms, val(ref, "I160", "GS") * 1852.0)
        assert close(ours.geometric_height_m, val(ref, "I140", "geometric_height") * 0.3048)
        assert ours.emitter_category == val(ref, "I020", "ECAT")
    else:
        assert ours.tod == val(ref, "I030", "ToD")
        assert ours.nucp == val(ref, "I090", "PA")
        if "I095" in ref:
            assert ours.nac_v == val(ref, "I095", "VA")
        if "I160" in ref:  # CroatiaControl's 0.23 definition gives GS in knots
            assert close(ours.ground_speed_ms, val(ref, "I160", "GS") * 1852.0 / 3600.0, 1e-5)
            assert close(ours.track_angle_deg, val(ref, "I160", "TA"))


def test_cat021_edition_2_6_matches_the_independent_decoder(independent_decoder):
    blocks = [
        cat021_26_record(),
        cat021_26_record(**{"131": None, "090": ((4, 0, None),), "157": None}),
        cat021_26_record(**{"040": ((0, 1, 0, 0, None),), "210": (0, 0, 0, 2), "071": None}),
    ]
    refs = independent_decoder(b"".join(blocks))
    assert len(refs) == len(blocks)
    for blk, ref in zip(blocks, refs, strict=True):
        ours, _ = cat021.decode_fast(blk[3:], 0, "2.6")
        assert isinstance(ours, cat021.Cat021Report), ours
        if "I071" not in ref:  # the time of reception, refined by I074 (FSI = +1 s)
            base = val(ref, "I073", "time_reception_position")
            assert ours.tod == math.floor(base) + 1 + 0.5
            ref = {**ref, "I071": {"time_applicability_position": {"val": ours.tod}}}
        check_cat021(ours, ref, v2=True)
    first, _ = cat021.decode_fast(blocks[0][3:], 0, "2.6")
    assert first.sigma_source == "nacp" and first.high_resolution
    assert first.callsign == "CAT21"  # 0x0C1532C60820: C A T 2 1 + 3 spaces
    second, _ = cat021.decode_fast(blocks[1][3:], 0, "2.6")
    assert second.nacp is None and second.nic == 0 and second.sigma_pos_m is None
    third, _ = cat021.decode_fast(blocks[2][3:], 0, "2.6")
    assert third.mops_version == 0 and third.nucp == 7 and third.sigma_source == "nacp"


def test_cat021_edition_0_23_matches_the_independent_decoder(independent_decoder):
    """The LEBL ADS-B file against asterix-decoder with CroatiaControl's edition 0.23
    definition (``asterix_cat021_0_23.xml`` from its repository; the PyPI package ships
    only 2.6): set ``SKYFUSE_ASTERIX_DECODER_DEFINITIONS`` to a folder holding it."""
    path = SHARED_DATA / ADSB_FILE
    folder = os.environ.get("SKYFUSE_ASTERIX_DECODER_DEFINITIONS")
    definition = Path(folder) / "asterix_cat021_0_23.xml" if folder else None
    if not path.exists() or definition is None or not definition.exists():
        pytest.skip("needs the LEBL ADS-B file and $SKYFUSE_ASTERIX_DECODER_DEFINITIONS")
    blocks = blocks_of(path)
    chosen = sorted({0, len(blocks) // 2, len(blocks) - 1, *range(1, len(blocks), 97)})
    refs = independent_decoder(b"".join(blocks[i] for i in chosen), (definition,))
    assert len(refs) == len(chosen)
    for i, ref in zip(chosen, refs, strict=True):
        ours, _ = cat021.decode_fast(blocks[i][3:], 0, "0.23")
        check_cat021(ours, ref, v2=False)


def test_cat020_matches_the_independent_decoder(independent_decoder):
    spec = gen.Cat_020_1_10
    rec = spec.cv_record.create(
        {
            "010": (("SAC", 1), ("SIC", 2)),
            "020": ((0, 1, 1, 1, 1, 1, 1, None), (0, 0, 0, 1, 0, 0, 0, None)),
            "140": 5000,
            "041": (("LAT", 2**24), ("LON", -(2**23))),
            "042": (("X", -1000), ("Y", 2000)),
            "161": (0, ("TRN", 77)),
            "170": ((0, 0, 1, 0, 0, 0, None),),
            "070": (0, 0, 0, 0, ("MODE3A", 0o7654)),
            "202": (("VX", -40), ("VY", 41)),
            "090": (0, 0, ("FL", 140)),
            "220": 0x123456,
            "110": 100,
            "105": 200,
            "500": {"SDP": (("X", 40), ("Y", 60), ("XY", 0xFFF0)), "SDH": 20},
        }
    )
    blk = spec.create([rec]).unparse().to_bytes()
    (ref,) = independent_decoder(blk)
    ours, end = cat020.decode_fast(blk[3:], 0)
    assert end == len(blk) - 3
    assert (ours.sac, ours.sic, ours.tod) == (1, 2, val(ref, "I140", "ToD"))
    assert ours.ground == bool(val(ref, "I020", "GBS"))
    assert (ours.lat, ours.lon) == (val(ref, "I041", "Lat"), val(ref, "I041", "Lon"))
    assert (ours.x_m, ours.y_m) == (val(ref, "I042", "X"), val(ref, "I042", "Y"))
    assert ours.track_number == val(ref, "I161", "TrkNb")
    assert ours.coasted == bool(val(ref, "I170", "CST"))
    assert ours.mode_3a == int(val(ref, "I070", "Mod3A"), 8)
    assert (ours.vx_ms, ours.vy_ms) == (val(ref, "I202", "Vx"), val(ref, "I202", "Vy"))
    assert ours.flight_level == val(ref, "I090", "FL")
    assert ours.mode_s == int(val(ref, "I220", "TAddr"), 16)
    assert close(ours.height_m, val(ref, "I110", "MHeight") * 0.3048)
    assert close(ours.geometric_height_m, val(ref, "I105", "geometric_height") * 0.3048)
    sdp = ref["I500"]["SDP"]
    assert (ours.sigma_x_m, ours.sigma_y_m) == (sdp["SDPx"]["val"], sdp["SDPy"]["val"])
    assert ours.cov_xy_m2 == sdp["SDPxy"]["val"] == -4.0
    assert ours.sigma_h_m == ref["I500"]["SDH"]["STD_GH"]["val"]


def test_adsb_positions_agree_with_multilateration_on_the_ground():
    """An independent physical check of the CAT021 0.23 and CAT010 decoding: the same
    aircraft (same 24-bit address) on the ground, its ADS-B position interpolated to the
    MLAT report time, both in the east/north plane of the MLAT reference point. A wrong
    LSB, sign or time item would put them hundreds of metres to kilometres apart."""
    import pymap3d
    from skyfuse.services.asterix import read_reports

    mlat_path, adsb_path = SHARED_DATA / CAT010_FILES[0], SHARED_DATA / ADSB_FILE
    if not (mlat_path.exists() and adsb_path.exists()):
        pytest.skip("LEBL 2016 files absent")
    ref = (41.29706278, 2.07844722, 4.0)  # the MLAT reference point (data README)
    mlat = [r for r in read_reports(mlat_path)[0] if getattr(r, "mode_s", None) is not None]
    adsb: dict[int, list] = {}
    for r in read_reports(adsb_path)[0]:
        adsb.setdefault(r.address, []).append(r)
    dist = []
    for r in mlat:
        track = adsb.get(r.mode_s)
        if not r.ground or not track:
            continue
        times = [a.time_ns for a in track]
        k = next((i for i, t in enumerate(times) if t >= r.time_ns), None)
        if k is None or k == 0 or times[k] - times[k - 1] > 3e9:
            continue
        w = (r.time_ns - times[k - 1]) / (times[k] - times[k - 1])
        lat = track[k - 1].lat + w * (track[k].lat - track[k - 1].lat)
        lon = track[k - 1].lon + w * (track[k].lon - track[k - 1].lon)
        e, n, _ = pymap3d.geodetic2enu(lat, lon, ref[2], *ref)
        dist.append(math.hypot(r.x_m - e, r.y_m - n))
    dist.sort()
    assert len(dist) > 1000
    assert dist[len(dist) // 2] < 15.0 and dist[9 * len(dist) // 10] < 40.0
