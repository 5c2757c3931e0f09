"""CAT062 (SDPS system tracks) → plain values, with libasterix (edition 1.20).

==========  =====================================================  ==================
item        content                                                kept as
==========  =====================================================  ==================
I062/010    SAC/SIC of the tracker                                 ``sac``, ``sic``
I062/015    service identification                                 ``service_id``
I062/070    time of track information, LSB 1/128 s                 ``tod``
I062/105    WGS-84 position, LSB 180/2^25 deg                      ``lat``, ``lon``
I062/100    system Cartesian position, LSB 0.5 m                   ``x``, ``y``
I062/185    Cartesian velocity, LSB 0.25 m/s                       ``vx``, ``vy``
I062/136    measured flight level, LSB 1/4 FL                      ``flight_level``
I062/130    calculated geometric altitude, LSB 6.25 ft             ``geometric_alt_ft``
I062/060    Mode-3/A code (V = 0), CH (code changed)               ``mode_3a``, ``mode_3a_changed``
I062/245    target identification                                  ``callsign``
I062/380    aircraft-derived data: ADR, ID, MHG, IAS (IAS or       ``mode_s``, ``callsign``
            Mach), TAS, SAL, FSS, BVR, GVR, RAN, TAR, TAN, GS,     (without I245), the
            IAR, MAC                                               ``downlinked`` dict
I062/040    track number (16 bits)                                 ``track_number``
I062/080    status: MON, SPI, CNF, SIM, TSB (first), TSE (last),   ``mono``, ``spi``,
            EMS (emergency)                                        ``confirmed``…,
                                                                   ``emergency``
I062/290    ages per technology (s)                                ``ages`` ("PSR", …)
I062/295    ages of the data (s)                                   ``data_ages`` ("MFL", …)
I062/500    accuracies: APC (x, y), COV, APW (lat, lon), ATV       ``sigma_*``, ``cov_xy``
I062/340    measured information of the last plot: SID, POS,       ``last_plot`` dict
            MDC, MDA, TYP
==========  =====================================================  ==================

``downlinked`` uses the names and units of :mod:`schemas.identity` (SI; selected
altitudes in FL: SAL → ``selected_altitude`` with ``selected_altitude_source`` 2 MCP/FCU
or 3 FMS, FSS → ``selected_altitude_mcp``; GVR → ``inertial_vertical_rate``).

Records that parse but carry an impossible value (time of day beyond one day, latitude
beyond ±90°, no I010) are rejected with a reason; malformed records are counted and
the rest of their block is skipped (ASTERIX records have no length field).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import asterix.generated as gen
from skyfuse.schemas.identity import FT_PER_MIN, KT

from .cat048 import decode_callsign
from .layout import compile_layout
from .pcap import iter_file_datagrams, split_datablocks
from .records import RecordError, iter_records, quantity, sub_quantity, sub_uint

SPEC = gen.Cat_062_1_20
CATEGORY = 62
LAYOUT = compile_layout(SPEC)


@dataclass(slots=True)
class Cat062Track:
    """One CAT062 track record in ASTERIX units (degrees, m, m/s, FL, s of day)."""

    sac: int
    sic: int
    service_id: int | None
    track_number: int | None
    tod: float
    lat: float | None = None
    lon: float | None = None
    x: float | None = None
    y: float | None = None
    vx: float | None = None
    vy: float | None = None
    flight_level: float | None = None
    geometric_alt_ft: float | None = None
    mode_3a: int | None = None
    mode_3a_changed: bool | None = None
    mode_s: int | None = None
    mono: bool | None = None
    confirmed: bool | None = None
    simulated: bool | None = None
    first: bool | None = None
    last: bool | None = None
    sigma_x: float | None = None
    sigma_y: float | None = None
    cov_xy: float | None = None
    sigma_lat: float | None = None
    sigma_lon: float | None = None
    sigma_vx: float | None = None
    sigma_vy: float | None = None
    callsign: str | None = None
    spi: bool | None = None
    emergency: str | None = None
    downlinked: dict[str, float] = field(default_factory=dict)
    ages: dict[str, float] = field(default_factory=dict)
    data_ages: dict[str, float] = field(default_factory=dict)
    last_plot: dict[str, Any] = field(default_factory=dict)


EMERGENCY_OF_EMS = {1: "general", 2: "medical", 3: "minimum_fuel", 4: "no_communications",
                    5: "unlawful_interference", 6: "downed_aircraft"}  # fmt: skip
"""I062/080 EMS → :class:`schemas.Emergency` value."""
_I380_QUANTITIES = {  # subfield → (our name, libasterix unit, factor to SI / FL)
    "MHG": ("magnetic_heading", "°", math.pi / 180), "TAS": ("true_airspeed", "kt", KT),
    "BVR": ("baro_vertical_rate", "ft/min", FT_PER_MIN),
    "GVR": ("inertial_vertical_rate", "ft/min", FT_PER_MIN),
    "RAN": ("roll_angle", "°", math.pi / 180), "TAN": ("true_track", "°", math.pi / 180),
    "GS": ("ground_speed", "NM/s", 1852.0), "IAR": ("indicated_airspeed", "kt", KT),
    "MAC": ("mach", "Mach", 1.0),
}  # fmt: skip


def decode_record(rec: Any) -> Cat062Track | str:
    """Values of one parsed CAT062 record, or a reject reason (count key)."""
    if not rec.items_regular:
        return "cat062_empty_record"
    i010 = rec.get_item("010")
    if i010 is None:
        return "cat062_no_data_source"
    tod = quantity(rec, "070", "s")
    if tod is None:
        return "cat062_no_time"
    if not 0.0 <= tod < 86_401.0:
        return "cat062_bad_time"
    i015 = rec.get_item("015")
    i040 = rec.get_item("040")
    trk = Cat062Track(
        sac=sub_uint(i010.variation, "SAC"),
        sic=sub_uint(i010.variation, "SIC"),
        service_id=i015.as_uint() if i015 is not None else None,
        track_number=i040.as_uint() if i040 is not None else None,
        tod=tod,
    )
    i105 = rec.get_item("105")
    if i105 is not None:
        trk.lat = sub_quantity(i105.variation, "LAT", "°")
        trk.lon = sub_quantity(i105.variation, "LON", "°")
        if not (-90.0 <= trk.lat <= 90.0 and -180.0 <= trk.lon <= 180.0):
            return "cat062_bad_position"
    i100 = rec.get_item("100")
    if i100 is not None:
        trk.x = sub_quantity(i100.variation, "X", "m")
        trk.y = sub_quantity(i100.variation, "Y", "m")
    i185 = rec.get_item("185")
    if i185 is not None:
        trk.vx = sub_quantity(i185.variation, "VX", "m/s")
        trk.vy = sub_quantity(i185.variation, "VY", "m/s")
    trk.flight_level = quantity(rec, "136", "FL")
    trk.geometric_alt_ft = quantity(rec, "130", "ft")
    _identity(rec, trk)
    i500 = rec.get_item("500")
    if i500 is not None:
        v = i500.variation
        apc = v.get_item("APC")
        if apc is not None:
            trk.sigma_x = sub_quantity(apc.variation, "X", "m")
            trk.sigma_y = sub_quantity(apc.variation, "Y", "m")
        cov = v.get_item("COV")
        if cov is not None:
            c = cov.variation.content.as_quantity("m")
            trk.cov_xy = c * abs(c)  # I500/COV = sign(Cov) √|Cov|
        apw = v.get_item("APW")
        if apw is not None:
            trk.sigma_lat = sub_quantity(apw.variation, "LAT", "°")
            trk.sigma_lon = sub_quantity(apw.variation, "LON", "°")
        atv = v.get_item("ATV")
        if atv is not None:
            trk.sigma_vx = sub_quantity(atv.variation, "X", "m/s")
            trk.sigma_vy = sub_quantity(atv.variation, "Y", "m/s")
    return trk


def _identity(rec: Any, trk: Cat062Track) -> None:
    """I060, I245, I380, I080, I290, I295 and I340 into ``trk``."""
    i060 = rec.get_item("060")
    if i060 is not None and sub_uint(i060.variation, "V") == 0:
        trk.mode_3a = sub_uint(i060.variation, "MODE3A")
        trk.mode_3a_changed = bool(sub_uint(i060.variation, "CH"))
    i245 = rec.get_item("245")
    if i245 is not None:
        trk.callsign = decode_callsign(sub_uint(i245.variation, "CHR"))
    i380 = rec.get_item("380")
    if i380 is not None:
        _aircraft_derived(i380.variation, trk)
    i080 = rec.get_item("080")
    if i080 is not None:
        v = i080.variation
        trk.mono = bool(sub_uint(v, "MON"))
        trk.spi = bool(sub_uint(v, "SPI"))
        trk.confirmed = sub_uint(v, "CNF") == 0
        for name, attr in (("SIM", "simulated"), ("TSB", "first"), ("TSE", "last")):
            sub = v.get_item(name)
            if sub is not None:
                setattr(trk, attr, bool(sub.as_uint()))
        ems = v.get_item("EMS")
        if ems is not None and ems.as_uint():
            trk.emergency = EMERGENCY_OF_EMS.get(ems.as_uint(), "undefined")
    for name, attr in (("290", "ages"), ("295", "data_ages")):
        item = rec.get_item(name)
        if item is not None:
            setattr(trk, attr, _ages(item.variation))
    i340 = rec.get_item("340")
    if i340 is not None:
        trk.last_plot = _measured(i340.variation)


def _aircraft_derived(v: Any, trk: Cat062Track) -> None:
    """I062/380 subfields into ``trk``."""
    adr = v.get_item("ADR")
    if adr is not None:
        trk.mode_s = adr.as_uint()
    ident = v.get_item("ID")
    if ident is not None and trk.callsign is None:
        trk.callsign = decode_callsign(ident.as_uint())
    out = trk.downlinked
    for sub, (name, unit, factor) in _I380_QUANTITIES.items():
        item = v.get_item(sub)
        if item is not None:
            out[name] = item.variation.content.as_quantity(unit) * factor
    ias = v.get_item("IAS")
    if ias is not None:  # IM = 0: IAS, LSB 2^-14 NM/s; IM = 1: Mach, LSB 0.001
        raw = sub_uint(ias.variation, "IAS")
        if sub_uint(ias.variation, "IM"):
            out.setdefault("mach", raw * 0.001)
        else:
            out.setdefault("indicated_airspeed", raw * 2.0**-14 * 1852.0)
    for sub, name in (("SAL", "selected_altitude"), ("FSS", "selected_altitude_mcp")):
        item = v.get_item(sub)
        if item is not None:
            out[name] = sub_quantity(item.variation, "ALT", "ft") / 100.0
            if sub == "SAL":
                out["selected_altitude_source"] = sub_uint(item.variation, "SRC")
    tar = v.get_item("TAR")
    if tar is not None:
        rate = sub_quantity(tar.variation, "ROT", "°/s")
        out["track_angle_rate"] = math.radians(rate)
        out["turn_indicator"] = sub_uint(tar.variation, "TI")


def _ages(v: Any) -> dict[str, float]:
    """The present subfields of I062/290 or I062/295, in seconds."""
    out = {}
    for nsp in v.cv_items_list:
        name = getattr(nsp, "cv_name", None)
        item = v.get_item(name) if name else None
        if item is not None:
            out[name] = item.variation.content.as_quantity("s")
    return out


def _measured(v: Any) -> dict[str, Any]:
    """I062/340 subfields (SID as ``radar_id`` "SAC-SIC", RHO NM, THETA °, MDC FL)."""
    out: dict[str, Any] = {}
    sid = v.get_item("SID")
    if sid is not None:
        out["radar_id"] = f"{sub_uint(sid.variation, 'SAC')}-{sub_uint(sid.variation, 'SIC')}"
    pos = v.get_item("POS")
    if pos is not None:
        out["rho_nm"] = sub_quantity(pos.variation, "RHO", "NM")
        out["theta_deg"] = sub_quantity(pos.variation, "THETA", "°")
    mdc = v.get_item("MDC")
    if mdc is not None:
        out["flight_level"] = sub_quantity(mdc.variation, "LMC", "FL")
        out["flight_level_not_validated"] = bool(sub_uint(mdc.variation, "V"))
        out["flight_level_garbled"] = bool(sub_uint(mdc.variation, "G"))
    mda = v.get_item("MDA")
    if mda is not None:
        out["mode_3a"] = sub_uint(mda.variation, "MODE3A")
        for flag, key in (("V", "not_validated"), ("G", "garbled"), ("L", "smoothed")):
            out[f"mode_3a_{key}"] = bool(sub_uint(mda.variation, flag))
    typ = v.get_item("TYP")
    if typ is not None:
        out["plot_type"] = sub_uint(typ.variation, "TYP")
    return out


def _decode_block(cat: int, data: bytes, stats: Counter, out: list[Cat062Track]) -> None:
    if cat != CATEGORY:
        stats[f"ignored_category_{cat}"] += 1
        return
    for rec in iter_records(SPEC, data):
        if isinstance(rec, RecordError):
            stats["cat062_malformed_record"] += 1
            return
        stats["cat062_records"] += 1
        trk = decode_record(rec)
        if isinstance(trk, str):
            stats[trk] += 1
        else:
            out.append(trk)


def decode_cat062(payload: bytes, stats: Counter | None = None) -> list[Cat062Track]:
    """Tracks of the CAT062 blocks in ``payload`` (one datagram or a raw file's bytes).

    Other categories, malformed blocks/records and rejected records are counted in
    ``stats`` (a Counter, created if not given); nothing raises on bad data."""
    stats = Counter() if stats is None else stats
    out: list[Cat062Track] = []
    for cat, data in split_datablocks(payload, stats):
        _decode_block(cat, data, stats, out)
    return out


def read_cat062(path: str | Path) -> tuple[list[Cat062Track], dict[str, int]]:
    """Tracks of a pcap or raw CAT062 file, and the counts by reason."""
    stats: Counter = Counter()
    out: list[Cat062Track] = []
    for dgram in iter_file_datagrams(path, stats):
        for cat, data in split_datablocks(dgram.payload, stats, raw_stream=dgram.raw_stream):
            _decode_block(cat, data, stats, out)
    return out, dict(stats)
