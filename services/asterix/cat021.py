"""CAT021 (ADS-B target reports) → plain values, editions 0.23–0.26 and 2.1–2.7.

The editions are libasterix's (``Cat_021_0_23`` … ``Cat_021_2_7``, :data:`EDITIONS`).
Nothing in a CAT021 record names its edition, and the two families have different
UAPs (0.2x: I010, I040, I030, I130, I080, …; 2.x: I010, I040, I161, I015, I071, I130,
I131, …), so the reader is told the edition or detects it per block
(:func:`block_fits`, used by :mod:`.surveillance`). The 2.x editions differ only by
extents added at the end of I040/I090/I271, so a later 2.x layout splits records of an
earlier one.

Items and LSBs (EUROCONTROL CAT021 edition 0.23 and 2.6):

===============  ==================================================  ==================
item             content                                             kept as
===============  ==================================================  ==================
I021/010         SAC/SIC                                             ``sac``, ``sic``
I021/040         GBS, SIM, TST, RAB, ATP (address type)               ``ground``, …
0.2x I021/030    time of day (of the position), LSB 1/128 s          ``tod``
2.x I021/071     time of applicability for position, 1/128 s         ``tod`` (first)
2.x I021/073     time of message reception for position, 1/128 s,    ``reception_tod``;
2.x I021/074     + high-precision fraction (LSB 2^-30 s, FSI)        ``tod`` if no I071
I021/130         WGS-84 lat/lon, LSB 180/2^23 ° (0.24-0.26:          ``lat``, ``lon``
                 180/2^25 °, 4 bytes each)
2.x I021/131     high-resolution lat/lon, LSB 180/2^30 °             (preferred)
I021/080         24-bit target address                               ``address``
I021/145         flight level, LSB 1/4 FL                            ``flight_level``
I021/140         geometric height, LSB 6.25 ft                       ``geometric_height_m``
0.2x I021/090    figure of merit: PA = NUCp (4 bits)                 ``nucp``
2.x I021/090     NUCr/NACv, NUCp/NIC, NICbaro, SIL, NACp, …          ``nac_v``, ``nucp`` or
                                                                     ``nic``, ``sil``, ``nacp``
0.2x I021/095    velocity accuracy (NUCr)                            ``nac_v``
2.x I021/210     MOPS version VN (0 DO-260, 1 DO-260A, 2 DO-260B)    ``mops_version``
I021/160         ground speed LSB 2^-14 NM/s (0.2x: signed; 2.x:     ``ground_speed_ms``,
                 15 bits + RE), track angle LSB 360/2^16 °           ``track_angle_deg``,
                                                                     ``v_east_ms``, ``v_north_ms``
I021/157, /155   geometric (else barometric) vertical rate,          ``vertical_rate_ms``
                 LSB 6.25 ft/min
I021/170         target identification (ICAO 6-bit chars)           ``callsign``
0.26, 2.x I070   Mode-3/A code                                       ``mode_3a``
I021/020         emitter category                                    ``emitter_category``
2.x I021/161     track number                                        ``track_number``
===============  ==================================================  ==================

Position σ (:mod:`skyfuse.schemas.adsb_quality`): NACp when reported (2.x, second extent of I090),
else NUCp (0.2x PA, or 2.x NUCp/NIC with MOPS version 0); ``sigma_source`` says which.
In 2.x with VN ≥ 1 the NUCp/NIC field is the NIC (an integrity, not an accuracy): kept
as ``nic``. Velocity σ from NUCr/NACv. Values are converted from the item bytes
(:mod:`.fields`), for the fast path and the libasterix path alike.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import asterix.generated as gen
from skyfuse.schemas import adsb_quality

from .fields import DAY_S, FT, NM, icao_chars, mode_3a, signed, signed_bits, unsigned
from .layout import RecordLayout, compile_layout, split_item_bytes
from .record_reject import RecordReject, wgs84_reject
from .records import item_bytes

CATEGORY = 21
#: Edition name ("0.23", "2.6", …) → libasterix specification.
EDITIONS = {f"{s.cv_edition[0]}.{s.cv_edition[1]}": s for s in gen.manifest["CATS"][21]}
#: The editions tried, in order, when the edition is detected from the data.
AUTO_CANDIDATES = ("2.7", "0.23")
REJECT_REASONS = (
    "cat021_no_data_source",
    "cat021_no_time",
    "cat021_bad_time",
    "cat021_no_position",
    "cat021_bad_position",
    "cat021_no_address",
)
TOD_LSB = 1.0 / 128.0
FT_PER_MIN = FT / 60.0


@dataclass(slots=True)
class Cat021Report:
    """One CAT021 ADS-B report in SI units (m, m/s, degrees, s of day). ``time_ns``
    (ns UTC of ``tod``) is filled by the stream (:mod:`.surveillance`)."""

    sac: int
    sic: int
    edition: str
    tod: float
    lat: float
    lon: float
    address: int
    reception_tod: float | None = None
    high_resolution: bool = False
    address_type: int | None = None
    ground: bool = False
    sim: bool = False
    tst: bool = False
    rab: bool = False
    flight_level: float | None = None
    geometric_height_m: float | None = None
    nucp: int | None = None
    nic: int | None = None
    nacp: int | None = None
    sil: int | None = None
    nac_v: int | None = None
    mops_version: int | None = None
    sigma_pos_m: float | None = None
    sigma_source: str | None = None
    sigma_vel_ms: float | None = None
    ground_speed_ms: float | None = None
    track_angle_deg: float | None = None
    v_east_ms: float | None = None
    v_north_ms: float | None = None
    vertical_rate_ms: float | None = None
    callsign: str | None = None
    mode_3a: int | None = None
    emitter_category: int | None = None
    track_number: int | None = None
    time_ns: int | None = None


@functools.cache
def layout(edition: str) -> RecordLayout:
    """The compiled UAP of an edition (``KeyError`` for an unknown name)."""
    return compile_layout(EDITIONS[edition])


def decode_items(items: Mapping[str, bytes], edition: str) -> Cat021Report | RecordReject:
    """Values of one record of ``edition`` given as item name → item bytes."""
    b = items.get("010")
    if b is None:
        return RecordReject("cat021_no_data_source", "record has no I021/010 (SAC/SIC)")
    sac, sic = b[0], b[1]
    v2 = edition.startswith("2.")
    tod, reception = _times_v2(items) if v2 else (_tod(items.get("030")), None)
    if tod is None:
        return RecordReject("cat021_no_time", "record has no time of the position", sac, sic)
    if not 0.0 <= tod < DAY_S + 1.0:
        return RecordReject("cat021_bad_time", f"time of day {tod} s is outside a day", sac, sic)
    pos = _position(items)
    if pos is None:
        return RecordReject("cat021_no_position", "record has no I021/130 or /131", sac, sic)
    bad = wgs84_reject(pos[0], pos[1], "I021/130", sac, sic)
    if bad is not None:
        return bad
    b = items.get("080")
    if b is None:
        return RecordReject("cat021_no_address", "record has no I021/080 address", sac, sic)
    r = Cat021Report(sac, sic, edition, tod, pos[0], pos[1], unsigned(b), reception)
    r.high_resolution = pos[2]
    _descriptor(items.get("040"), v2, r)
    _quality(items, v2, r)
    _velocity(items, v2, r)
    _identity(items, v2, r)
    return r


def _tod(b: bytes | None) -> float | None:
    return None if b is None else unsigned(b) * TOD_LSB


def _times_v2(items: Mapping[str, bytes]) -> tuple[float | None, float | None]:
    """(time of the position, time of reception of the position) for 2.x: I071 if
    present, else I073 refined by I074 (full-second indication FSI and 30-bit fraction)."""
    reception = _tod(items.get("073"))
    fine = items.get("074")
    if reception is not None and fine is not None:
        fsi = fine[0] >> 6
        frac = (unsigned(fine) & 0x3FFFFFFF) / 2**30
        whole = math.floor(reception) + {1: 1, 2: -1}.get(fsi, 0)
        reception = whole + frac
    applicability = _tod(items.get("071"))
    return (applicability if applicability is not None else reception), reception


def _position(items: Mapping[str, bytes]) -> tuple[float, float, bool] | None:
    b = items.get("131")
    if b is not None:
        scale = 180.0 / 2**30
        return signed(b[0:4]) * scale, signed(b[4:8]) * scale, True
    b = items.get("130")
    if b is None:
        return None
    if len(b) == 8:  # editions 0.24-0.26: 4 bytes each, LSB 180/2^25
        scale = 180.0 / 2**25
        return signed(b[0:4]) * scale, signed(b[4:8]) * scale, False
    scale = 180.0 / 2**23
    return signed(b[0:3]) * scale, signed(b[3:6]) * scale, False


def _descriptor(b: bytes | None, v2: bool, r: Cat021Report) -> None:
    if b is None:
        return
    if not v2:  # 0.2x: DCR GBS SIM TST RAB SAA SPI spare | ATP(3) ARC(2) spare(3)
        flags = b[0]
        r.ground, r.sim, r.tst = bool(flags & 0x40), bool(flags & 0x20), bool(flags & 0x10)
        r.rab = bool(flags & 0x08)
        r.address_type = b[1] >> 5
        return
    r.address_type = b[0] >> 5  # ATP(3) ARC(2) RC RAB FX | DCR GBS SIM TST SAA CL(2) FX
    r.rab = bool(b[0] & 0x02)
    if len(b) > 1:
        r.ground, r.sim, r.tst = bool(b[1] & 0x40), bool(b[1] & 0x20), bool(b[1] & 0x10)


def _quality(items: Mapping[str, bytes], v2: bool, r: Cat021Report) -> None:
    b = items.get("090")
    if not v2:
        if b is not None:
            r.nucp = b[1] & 0x0F
        b = items.get("095")
        if b is not None:
            r.nac_v = b[0]
    else:
        vn = items.get("210")
        if vn is not None:
            r.mops_version = (vn[0] >> 3) & 0x07
        if b is not None:
            r.nac_v = b[0] >> 5
            if r.mops_version == 0:
                r.nucp = (b[0] >> 1) & 0x0F
            else:
                r.nic = (b[0] >> 1) & 0x0F
            if len(b) > 1:
                r.sil, r.nacp = (b[1] >> 5) & 0x03, (b[1] >> 1) & 0x0F
    if r.nacp is not None:
        r.sigma_pos_m = adsb_quality.position_sigma_nacp(r.nacp)
        r.sigma_source = "nacp"
    elif r.nucp is not None:
        r.sigma_pos_m = adsb_quality.position_sigma_nucp(r.nucp)
        r.sigma_source = "nucp"
    r.sigma_vel_ms = adsb_quality.velocity_sigma(r.nac_v)


def _velocity(items: Mapping[str, bytes], v2: bool, r: Cat021Report) -> None:
    b = items.get("160")
    if b is not None:
        raw = unsigned(b[0:2])
        gs = (raw & 0x7FFF) if v2 else signed(b[0:2])
        r.ground_speed_ms = gs * (NM / 16384.0)
        r.track_angle_deg = unsigned(b[2:4]) * (360.0 / 65536.0)
        ta = math.radians(r.track_angle_deg)
        r.v_east_ms = r.ground_speed_ms * math.sin(ta)
        r.v_north_ms = r.ground_speed_ms * math.cos(ta)
    for key in ("157", "155"):
        b = items.get(key)
        if b is not None:
            raw = unsigned(b)
            rate = signed_bits(raw, 15) if v2 else signed(b)
            r.vertical_rate_ms = rate * 6.25 * FT_PER_MIN
            break


def _identity(items: Mapping[str, bytes], v2: bool, r: Cat021Report) -> None:
    b = items.get("145")
    if b is not None:
        r.flight_level = signed(b) * 0.25
    b = items.get("140")
    if b is not None:
        r.geometric_height_m = signed(b) * 6.25 * FT
    b = items.get("170")
    if b is not None:
        r.callsign = icao_chars(b)
    b = items.get("070")
    if b is not None:
        r.mode_3a = (unsigned(b) & 0x0FFF) if v2 else mode_3a(b)
    b = items.get("020")
    if b is not None:
        r.emitter_category = b[0]
    b = items.get("161")
    if b is not None:
        r.track_number = unsigned(b) & 0x0FFF


def decode_record(rec: Any, edition: str) -> Cat021Report | RecordReject:
    """Values of one record parsed by libasterix with ``EDITIONS[edition]``."""
    return decode_items(item_bytes(rec), edition)


def decode_fast(
    data: bytes, pos: int, edition: str
) -> tuple[Cat021Report | RecordReject, int] | None:
    """Decode the record at ``pos`` with the compiled layout of ``edition``: ``(values,
    end offset)``, or ``None`` when it is not well formed in that edition."""
    split = split_item_bytes(data, pos, layout(edition))
    if split is None:
        return None
    items, end = split
    return decode_items(items, edition), end


def block_fits(data: bytes, edition: str) -> bool:
    """Whether every record of a block's record bytes splits in ``edition`` and has what a
    usable report needs (I010, I080, the edition's time of the position within a day, a
    position within WGS-84 ranges): the test that picks the edition of a block."""
    pos, n = 0, len(data)
    lay = layout(edition)
    time_items = ("071", "073") if edition.startswith("2.") else ("030",)
    while pos < n:
        split = split_item_bytes(data, pos, lay)
        if split is None:
            return False
        items, pos = split
        if "010" not in items or "080" not in items:
            return False
        tod = next((_tod(items[k]) for k in time_items if k in items), None)
        where = _position(items)
        if tod is None or tod >= DAY_S + 1.0 or where is None:
            return False
        if not (-90.0 <= where[0] <= 90.0 and -180.0 <= where[1] <= 180.0):
            return False
    return n > 0
