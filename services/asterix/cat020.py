"""CAT020 (multilateration and WAM target reports) → plain values, edition 1.10.

libasterix has editions 1.9, 1.10 and 1.11 (same UAP; 1.10 adds an I020 extent); 1.10
is used, as in the independent CroatiaControl decoder. No CAT020 recording is
available: the decoder is tested on records built with libasterix's encoder and
decoded by that independent decoder.

==========  ================================================  ========================
item        content                                           kept as
==========  ================================================  ========================
I020/010    SAC/SIC                                           ``sac``, ``sic``
I020/020    SSR, MS, HF, VDL4, UAT, DME, OT (technologies     ``technologies`` (bit set,
            used, 0 = used); RAB, SPI, CHN, GBS, CRT, SIM,    SSR = 0x40 … OT = 0x01),
            TST                                               ``ground``, ``sim``, ``tst``
I020/140    time of day, LSB 1/128 s                          ``tod``
I020/041    WGS-84 lat/lon, LSB 180/2^25 °                    ``lat``, ``lon``
I020/042    x, y of the system reference point, LSB 0.5 m     ``x_m``, ``y_m``
I020/161    track number (12 bits)                            ``track_number``
I020/170    CNF, TRE, CST                                     ``confirmed``, ``last``,
                                                              ``coasted``
I020/070    Mode-3/A (V = 0, G = 0 only)                      ``mode_3a``
I020/202    VX, VY, LSB 0.25 m/s                              ``vx_ms``, ``vy_ms``
I020/090    flight level, LSB 1/4 FL (V = 0, G = 0 only)      ``flight_level``
I020/220    24-bit target address                             ``mode_s``
I020/245    target identification                             ``callsign``
I020/110    measured height (local Cartesian), LSB 6.25 ft    ``height_m``
I020/105    geometric height (WGS-84), LSB 6.25 ft            ``geometric_height_m``
I020/500    SDP: σx, σy (LSB 0.25 m), covariance σxy (LSB     ``sigma_x_m``,
            0.25 m², two's complement); SDH: σ of the         ``sigma_y_m``,
            geometric height (LSB 0.5 m); DOP (x, y, xy)      ``cov_xy_m2``, ``sigma_h_m``
==========  ================================================  ========================

σxy is signed here (a covariance, as the CroatiaControl decoder reads it); libasterix
0.36 declares it unsigned.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import asterix.generated as gen

from .fields import FT, flight_level, icao_chars, mode_3a, signed, unsigned
from .layout import compile_layout, split_item_bytes
from .record_reject import RecordReject, source_and_time, wgs84_reject
from .records import item_bytes

SPEC = gen.Cat_020_1_10
CATEGORY = 20
LAYOUT = compile_layout(SPEC)
REJECT_REASONS = (
    "cat020_no_data_source",
    "cat020_no_time",
    "cat020_bad_time",
    "cat020_no_position",
    "cat020_bad_position",
)


@dataclass(slots=True)
class Cat020Report:
    """One CAT020 target report; ``time_ns`` is filled by the stream."""

    sac: int
    sic: int
    tod: float
    technologies: int | None = None
    ground: bool = False
    sim: bool = False
    tst: bool = False
    rab: bool = False
    lat: float | None = None
    lon: float | None = None
    x_m: float | None = None
    y_m: float | None = None
    track_number: int | None = None
    confirmed: bool | None = None
    last: bool = False
    coasted: bool | None = None
    mode_3a: int | None = None
    vx_ms: float | None = None
    vy_ms: float | None = None
    flight_level: float | None = None
    mode_s: int | None = None
    callsign: str | None = None
    height_m: float | None = None
    geometric_height_m: float | None = None
    sigma_x_m: float | None = None
    sigma_y_m: float | None = None
    cov_xy_m2: float | None = None
    sigma_h_m: float | None = None
    time_ns: int | None = None


def decode_items(items: Mapping[str, bytes]) -> Cat020Report | RecordReject:
    """Values of one record given as item name → item bytes."""
    header = source_and_time(items, CATEGORY)
    if isinstance(header, RecordReject):
        return header
    sac, sic, tod = header
    if "041" not in items and "042" not in items:
        return RecordReject("cat020_no_position", "record has no I020/041 or /042", sac, sic)
    r = Cat020Report(sac, sic, tod)
    b = items.get("020")
    if b is not None:
        r.technologies = (b[0] >> 1) & 0x7F
        if len(b) > 1:
            r.rab, r.ground = bool(b[1] & 0x80), bool(b[1] & 0x10)
            r.sim, r.tst = bool(b[1] & 0x04), bool(b[1] & 0x02)
    b = items.get("041")
    if b is not None:
        r.lat = signed(b[0:4]) * (180.0 / 2**25)
        r.lon = signed(b[4:8]) * (180.0 / 2**25)
        bad = wgs84_reject(r.lat, r.lon, "I020/041", sac, sic)
        if bad is not None:
            return bad
    b = items.get("042")
    if b is not None:
        r.x_m, r.y_m = signed(b[0:3]) * 0.5, signed(b[3:6]) * 0.5
    _track(items, r)
    b = items.get("500")
    if b is not None:
        _accuracy(b, r)
    return r


def _track(items: Mapping[str, bytes], r: Cat020Report) -> None:
    b = items.get("161")
    if b is not None:
        r.track_number = unsigned(b) & 0x0FFF
    b = items.get("170")
    if b is not None:
        r.confirmed = not b[0] & 0x80
        r.last, r.coasted = bool(b[0] & 0x40), bool(b[0] & 0x20)
    b = items.get("070")
    if b is not None:
        r.mode_3a = mode_3a(b)
    b = items.get("202")
    if b is not None:
        r.vx_ms, r.vy_ms = signed(b[0:2]) * 0.25, signed(b[2:4]) * 0.25
    b = items.get("090")
    if b is not None:
        r.flight_level = flight_level(b)
    b = items.get("220")
    if b is not None:
        r.mode_s = unsigned(b)
    b = items.get("245")
    if b is not None:
        r.callsign = icao_chars(b[1:7])
    b = items.get("110")
    if b is not None:
        r.height_m = signed(b) * 6.25 * FT
    b = items.get("105")
    if b is not None:
        r.geometric_height_m = signed(b) * 6.25 * FT


def _accuracy(b: bytes, r: Cat020Report) -> None:
    """I020/500 compound: FSPEC (DOP, SDP, SDH), DOP 6 bytes, SDP 6 bytes, SDH 2 bytes."""
    fspec, pos = b[0], 1
    if fspec & 0x80:
        pos += 6  # DOP: dimensionless, not kept
    if fspec & 0x40:
        r.sigma_x_m = unsigned(b[pos : pos + 2]) * 0.25
        r.sigma_y_m = unsigned(b[pos + 2 : pos + 4]) * 0.25
        r.cov_xy_m2 = signed(b[pos + 4 : pos + 6]) * 0.25
        pos += 6
    if fspec & 0x20:
        r.sigma_h_m = unsigned(b[pos : pos + 2]) * 0.5


def decode_record(rec: Any) -> Cat020Report | RecordReject:
    """Values of one record parsed by libasterix (``Cat_020_1_10``)."""
    return decode_items(item_bytes(rec))


def decode_fast(data: bytes, pos: int) -> tuple[Cat020Report | RecordReject, int] | None:
    """Decode the record at ``pos`` with the compiled layout: ``(values, end offset)``,
    or ``None`` when it is not well formed."""
    split = split_item_bytes(data, pos, LAYOUT)
    if split is None:
        return None
    items, end = split
    return decode_items(items), end
