"""CAT034 (monoradar service messages) → plain values, with libasterix (edition 1.29).

==========  ===============================================  ======================
item        content                                          kept as
==========  ===============================================  ======================
I034/010    SAC/SIC                                          ``sac``, ``sic``
I034/000    message type: 1 North marker, 2 sector crossing  ``message_type``
I034/030    time of day, LSB 1/128 s                         ``tod``
I034/020    sector azimuth, LSB 360/2^8 deg                  ``sector_deg``
I034/041    antenna rotation period, LSB 1/128 s             ``period_s``
I034/120    WGS-84 height (m), lat/lon LSB 180/2^23 deg      ``lat``, ``lon``, ``height``
==========  ===============================================  ======================
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import asterix.generated as gen

from .layout import build_fspec, compile_layout, split_record
from .records import quantity, sub_quantity, sub_uint

SPEC = gen.Cat_034_1_29
CATEGORY = 34
NORTH_MARKER = 1
SECTOR_CROSSING = 2
TOD_WRAP = 86_400 * 128
LAYOUT = compile_layout(SPEC)


@dataclass(slots=True)
class Cat034Message:
    """One CAT034 service message in ASTERIX units (degrees, s of day, m)."""

    sac: int
    sic: int
    message_type: int
    tod: float | None
    sector_deg: float | None
    period_s: float | None
    lat: float | None
    lon: float | None
    height: float | None


def decode_record(rec: Any) -> Cat034Message | str:
    """Values of one parsed CAT034 record, or a reject reason (count key)."""
    i010 = rec.get_item("010")
    if i010 is None:
        return "cat034_no_data_source"
    i000 = rec.get_item("000")
    if i000 is None:
        return "cat034_no_message_type"
    tod = quantity(rec, "030", "s")
    if tod is not None and not 0.0 <= tod < 86_401.0:
        return "cat034_bad_time"
    sector = quantity(rec, "020", "°")
    period = quantity(rec, "041", "s")
    lat = lon = height = None
    i120 = rec.get_item("120")
    if i120 is not None:
        v = i120.variation
        height = sub_quantity(v, "HGT", "m")
        lat = sub_quantity(v, "LAT", "°")
        lon = sub_quantity(v, "LON", "°")
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            lat = lon = height = None
    return Cat034Message(
        sub_uint(i010.variation, "SAC"),
        sub_uint(i010.variation, "SIC"),
        i000.as_uint(),
        tod,
        sector,
        period,
        lat,
        lon,
        height,
    )


def _raw_items(
    *,
    sac: int,
    sic: int,
    message_type: int,
    tod: float,
    sector_deg: float | None = None,
    period_s: float | None = None,
    position: tuple[float, float, float] | None = None,
) -> dict[str, Any]:
    raw: dict[str, Any] = {
        "010": (sac, sic),
        "000": message_type,
        "030": round(tod * 128.0) % TOD_WRAP,
    }
    if sector_deg is not None:
        raw["020"] = round(sector_deg * 256.0 / 360.0) % 256
    if period_s is not None:
        raw["041"] = min(0xFFFF, max(0, round(period_s * 128.0)))
    if position is not None:
        lat, lon, hgt = position
        scale = 2**23 / 180.0
        raw["120"] = (
            max(-32768, min(32767, round(hgt))) & 0xFFFF,
            round(lat * scale) & 0xFFFFFF,
            round(lon * scale) & 0xFFFFFF,
        )
    return raw


def build_record(**values: Any) -> Any:
    """A libasterix CAT034 record (arguments as for :func:`encode_record`)."""
    raw = _raw_items(**values)
    items: dict[str, Any] = {
        "010": (("SAC", raw["010"][0]), ("SIC", raw["010"][1])),
        "000": raw["000"],
        "030": raw["030"],
    }
    for key in ("020", "041"):
        if key in raw:
            items[key] = raw[key]
    if "120" in raw:
        h, la, lo = raw["120"]
        items["120"] = (("HGT", h), ("LAT", la), ("LON", lo))
    return SPEC.cv_record.create(items)


def encode_record(
    *,
    sac: int,
    sic: int,
    message_type: int,
    tod: float,
    sector_deg: float | None = None,
    period_s: float | None = None,
    position: tuple[float, float, float] | None = None,
) -> bytes:
    """Bytes of one CAT034 record: I010, I000, I030, and I020 (sector azimuth), I041
    (rotation period), I120 (lat deg, lon deg, height m) when given. Identical to
    ``build_record(...).unparse()`` (differential test), packed directly."""
    raw = _raw_items(
        sac=sac,
        sic=sic,
        message_type=message_type,
        tod=tod,
        sector_deg=sector_deg,
        period_s=period_s,
        position=position,
    )
    order = [k for k in ("010", "000", "030", "020", "041", "120") if k in raw]
    body = bytearray(raw["010"])
    body.append(raw["000"])
    body += raw["030"].to_bytes(3, "big")
    if "020" in raw:
        body.append(raw["020"])
    if "041" in raw:
        body += raw["041"].to_bytes(2, "big")
    if "120" in raw:
        h, la, lo = raw["120"]
        body += h.to_bytes(2, "big") + la.to_bytes(3, "big") + lo.to_bytes(3, "big")
    return build_fspec(LAYOUT, order) + bytes(body)


def decode_fast(data: bytes, pos: int) -> tuple[Cat034Message | str, int] | None:
    """Like :func:`decode_record` for the record at ``pos`` without libasterix objects:
    ``(message or reject reason, end offset)``, or ``None`` if the record is not well
    formed (the caller re-parses with libasterix for the error)."""
    split = split_record(data, pos, LAYOUT)
    if isinstance(split, str):
        return None
    end, items = split
    span = items.get("010")
    if span is None:
        return "cat034_no_data_source", end
    sac, sic = data[span[0]], data[span[0] + 1]
    span = items.get("000")
    if span is None:
        return "cat034_no_message_type", end
    mtype = data[span[0]]
    tod = None
    span = items.get("030")
    if span is not None:
        tod = int.from_bytes(data[span[0] : span[1]], "big") / 128.0
        if not 0.0 <= tod < 86_401.0:
            return "cat034_bad_time", end
    span = items.get("020")
    sector = None if span is None else data[span[0]] * (360.0 / 256.0)
    span = items.get("041")
    period = None if span is None else int.from_bytes(data[span[0] : span[1]], "big") / 128.0
    lat = lon = height = None
    span = items.get("120")
    if span is not None:
        s0 = span[0]
        height = float(int.from_bytes(data[s0 : s0 + 2], "big", signed=True))
        lat = int.from_bytes(data[s0 + 2 : s0 + 5], "big", signed=True) * (180.0 / 2**23)
        lon = int.from_bytes(data[s0 + 5 : s0 + 8], "big", signed=True) * (180.0 / 2**23)
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            lat = lon = height = None
    return Cat034Message(sac, sic, mtype, tod, sector, period, lat, lon, height), end
