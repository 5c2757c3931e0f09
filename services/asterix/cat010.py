"""CAT010 (surface movement: SMR, airport multilateration) → plain values (edition 1.1).

Message types (I010/000): 1 target report → :class:`Cat010Report`; 2 start of update
cycle, 3 periodic status, 4 event-triggered status → :class:`Cat010Status`; anything
else, or a record without I010/I000/I140 or a target report without a position, →
:class:`RecordReject` with a reason from :data:`REJECT_REASONS`. A target report
without a position but with I170 TRE = 1 (last report of a track: the SMR sends these
as track ends, I161 + I170 only) is kept as a report without position, ``last`` set.

Items and LSBs (EUROCONTROL CAT010 edition 1.1):

==========  ==============================================  ============================
item        content                                         kept as
==========  ==============================================  ============================
I010/010    SAC/SIC                                         ``sac``, ``sic``
I010/000    message type                                    ``message_type``
I010/020    TYP (0 SSR MLAT, 1 Mode S MLAT, 2 ADS-B, 3 PSR,  ``typ``, ``ground`` (GBS),
            4 magnetic loop, 5 HF MLAT, 7 other), GBS, SIM,  ``sim``, ``tst``, ``rab``,
            TST, RAB, TOT (1 aircraft, 2 ground vehicle,     ``target_type``
            3 helicopter)
I010/140    time of day, LSB 1/128 s                        ``tod`` (s since midnight UTC)
I010/040    RHO LSB 1 m, THETA LSB 360/2^16 °               ``rho_m``, ``theta_deg``
I010/041    WGS-84 lat/lon, LSB 180/2^31 °                  ``lat``, ``lon``
I010/042    x (east), y (north), LSB 1 m, of the sensor     ``x_m``, ``y_m``
I010/200    ground speed LSB 2^-14 NM/s, track angle        ``ground_speed_ms`` (m/s),
            LSB 360/2^16 °                                  ``track_angle_deg``
I010/202    VX, VY, LSB 0.25 m/s                            ``vx_ms``, ``vy_ms``
I010/210    AX, AY, LSB 0.25 m/s²                           ``ax``, ``ay``
I010/161    track number (12 bits)                          ``track_number``
I010/170    CNF, TRE, CST, STH (+ DOU in the 1st extent)    ``confirmed``, ``last``,
                                                            ``coasted``, ``smoothed``
I010/060    Mode-3/A (V = 0, G = 0 only)                    ``mode_3a``
I010/220    24-bit target address                           ``mode_s``
I010/245    target identification (ICAO 6-bit chars)        ``callsign``
I010/090    flight level LSB 1/4 FL (V = 0, G = 0 only)     ``flight_level``
I010/091    measured height, LSB 6.25 ft                    ``height_m``
I010/270    length, width (LSB 1 m), orientation            ``length_m``, ``width_m``,
            (LSB 360/2^7 °)                                 ``orientation_deg``
I010/500    σx, σy (LSB 0.25 m), covariance (LSB 0.25 m²)   ``sigma_x_m``, ``sigma_y_m``,
                                                            ``cov_xy_m2``
I010/550    NOGO, OVL, TSV, DIV, TTF (status messages)      :class:`Cat010Status`
==========  ==============================================  ============================

The velocity and acceleration LSBs are 0.25 m/s and 0.25 m/s² as in the CAT010
specification (their stated ranges, ±8192 m/s in 16 bits and ±31 m/s² in 8 bits, need
them) and in the independent CroatiaControl decoder; libasterix 0.36's ``Cat_010_1_1``
has 1/16 for both, which the recordings contradict (|(VX, VY)| equals I200's ground
speed with 0.25, not with 1/16). Values are therefore converted here from the item
bytes (:mod:`.fields`), for the compiled-layout fast path (:func:`decode_fast`) and the
libasterix path (:func:`decode_record`) alike.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import asterix.generated as gen

from .fields import (
    FT,
    NM,
    flight_level,
    icao_chars,
    mode_3a,
    signed,
    unsigned,
)
from .layout import compile_layout, split_item_bytes
from .record_reject import RecordReject, source_and_time, wgs84_reject
from .records import item_bytes

SPEC = gen.Cat_010_1_1
CATEGORY = 10
LAYOUT = compile_layout(SPEC)
TARGET_REPORT = 1
START_OF_UPDATE_CYCLE = 2
PERIODIC_STATUS = 3
EVENT_STATUS = 4
#: I010/020 TYP.
REPORT_TYPES = {
    0: "SSR multilateration",
    1: "Mode S multilateration",
    2: "ADS-B",
    3: "PSR",
    4: "magnetic loop",
    5: "HF multilateration",
    6: "not defined",
    7: "other",
}
REJECT_REASONS = (
    "cat010_no_data_source",
    "cat010_no_message_type",
    "cat010_no_time",
    "cat010_bad_time",
    "cat010_no_position",
    "cat010_bad_position",
    "cat010_unknown_message_type",
)
VELOCITY_LSB = 0.25  # m/s, I010/202
ACCEL_LSB = 0.25  # m/s², I010/210


@dataclass(slots=True)
class Cat010Report:
    """One CAT010 target report (message type 1). ``time_ns`` (ns UTC) is filled by the
    stream that resolves the date (:mod:`.surveillance`)."""

    sac: int
    sic: int
    tod: float
    typ: int | None = None
    ground: bool = False
    sim: bool = False
    tst: bool = False
    rab: bool = False
    target_type: int | None = None
    rho_m: float | None = None
    theta_deg: float | None = None
    x_m: float | None = None
    y_m: float | None = None
    lat: float | None = None
    lon: float | None = None
    ground_speed_ms: float | None = None
    track_angle_deg: float | None = None
    vx_ms: float | None = None
    vy_ms: float | None = None
    ax: float | None = None
    ay: float | None = None
    track_number: int | None = None
    confirmed: bool | None = None
    last: bool = False
    coasted: int | None = None
    smoothed: bool | None = None
    mode_3a: int | None = None
    mode_s: int | None = None
    callsign: str | None = None
    flight_level: float | None = None
    height_m: float | None = None
    length_m: float | None = None
    width_m: float | None = None
    orientation_deg: float | None = None
    sigma_x_m: float | None = None
    sigma_y_m: float | None = None
    cov_xy_m2: float | None = None
    time_ns: int | None = None


@dataclass(slots=True)
class Cat010Status:
    """A CAT010 start-of-update-cycle (type 2) or status message (types 3, 4); I550
    system status when present (NOGO 0 operational, 1 degraded, 2 NOGO; overload; time
    source invalid; diversity degraded; test target failure)."""

    sac: int
    sic: int
    message_type: int
    tod: float
    nogo: int | None = None
    overload: bool | None = None
    time_source_invalid: bool | None = None
    diversity_degraded: bool | None = None
    test_target_failure: bool | None = None
    time_ns: int | None = None


Cat010Record = Cat010Report | Cat010Status | RecordReject


def decode_items(items: Mapping[str, bytes]) -> Cat010Record:
    """Values of one record given as item name → item bytes."""
    header = source_and_time(items, CATEGORY)
    if isinstance(header, RecordReject):
        return header
    sac, sic, tod = header
    b = items.get("000")
    if b is None:
        return RecordReject("cat010_no_message_type", "record has no I010/000", sac, sic)
    mtype = b[0]
    if mtype == TARGET_REPORT:
        return _target_report(items, sac, sic, tod)
    if mtype in (START_OF_UPDATE_CYCLE, PERIODIC_STATUS, EVENT_STATUS):
        return _status(items, sac, sic, mtype, tod)
    detail = f"I010/000 message type = {mtype} is not 1-4"
    return RecordReject("cat010_unknown_message_type", detail, sac, sic)


def _status(items: Mapping[str, bytes], sac: int, sic: int, mtype: int, tod: float) -> Any:
    msg = Cat010Status(sac, sic, mtype, tod)
    b = items.get("550")
    if b is not None:
        v = b[0]
        msg.nogo = v >> 6
        msg.overload = bool(v & 0x20)
        msg.time_source_invalid = bool(v & 0x10)
        msg.diversity_degraded = bool(v & 0x08)
        msg.test_target_failure = bool(v & 0x04)
    return msg


def _target_report(items: Mapping[str, bytes], sac: int, sic: int, tod: float) -> Any:
    r = Cat010Report(sac, sic, tod)
    _track(items, r)
    if not ("040" in items or "041" in items or "042" in items) and not r.last:
        detail = "target report has no position (I010/040, /041 or /042)"
        return RecordReject("cat010_no_position", detail, sac, sic)
    b = items.get("020")
    if b is not None:
        r.typ = b[0] >> 5
        r.ground = bool(b[0] & 0x04)
        if len(b) > 1:
            r.sim, r.tst, r.rab = bool(b[1] & 0x80), bool(b[1] & 0x40), bool(b[1] & 0x20)
            r.target_type = (b[1] >> 1) & 0x03
    _position(items, r)
    bad = wgs84_reject(r.lat, r.lon, "I010/041", sac, sic)
    if bad is not None:
        return bad
    b = items.get("060")
    if b is not None:
        r.mode_3a = mode_3a(b)
    b = items.get("220")
    if b is not None:
        r.mode_s = unsigned(b)
    b = items.get("245")
    if b is not None:
        r.callsign = icao_chars(b[1:7])
    b = items.get("090")
    if b is not None:
        r.flight_level = flight_level(b)
    b = items.get("091")
    if b is not None:
        r.height_m = signed(b) * 6.25 * FT
    b = items.get("270")
    if b is not None:
        r.length_m = float(b[0] >> 1)
        if len(b) > 1:
            r.orientation_deg = (b[1] >> 1) * (360.0 / 128.0)
        if len(b) > 2:
            r.width_m = float(b[2] >> 1)
    b = items.get("500")
    if b is not None:
        r.sigma_x_m, r.sigma_y_m = b[0] * 0.25, b[1] * 0.25
        r.cov_xy_m2 = signed(b[2:4]) * 0.25
    return r


def _position(items: Mapping[str, bytes], r: Cat010Report) -> None:
    b = items.get("040")
    if b is not None:
        r.rho_m = float(unsigned(b[0:2]))
        r.theta_deg = unsigned(b[2:4]) * (360.0 / 65536.0)
    b = items.get("041")
    if b is not None:
        r.lat = signed(b[0:4]) * (180.0 / 2**31)
        r.lon = signed(b[4:8]) * (180.0 / 2**31)
    b = items.get("042")
    if b is not None:
        r.x_m, r.y_m = float(signed(b[0:2])), float(signed(b[2:4]))


def _track(items: Mapping[str, bytes], r: Cat010Report) -> None:
    b = items.get("200")
    if b is not None:
        r.ground_speed_ms = unsigned(b[0:2]) * (NM / 16384.0)
        r.track_angle_deg = unsigned(b[2:4]) * (360.0 / 65536.0)
    b = items.get("202")
    if b is not None:
        r.vx_ms, r.vy_ms = signed(b[0:2]) * VELOCITY_LSB, signed(b[2:4]) * VELOCITY_LSB
    b = items.get("210")
    if b is not None:
        r.ax, r.ay = signed(b[0:1]) * ACCEL_LSB, signed(b[1:2]) * ACCEL_LSB
    b = items.get("161")
    if b is not None:
        r.track_number = unsigned(b) & 0x0FFF
    b = items.get("170")
    if b is not None:
        r.confirmed = not b[0] & 0x80
        r.last = bool(b[0] & 0x40)
        r.coasted = (b[0] >> 4) & 0x03
        r.smoothed = bool(b[0] & 0x02)


def decode_record(rec: Any) -> Cat010Record:
    """Values of one record parsed by libasterix (``Cat_010_1_1`` record)."""
    return decode_items(item_bytes(rec))


def decode_fast(data: bytes, pos: int) -> tuple[Cat010Record, int] | None:
    """Decode the record at ``pos`` with the compiled layout: ``(values, end offset)``,
    or ``None`` when the record is not well formed (the caller re-parses it with
    libasterix for the authoritative error)."""
    split = split_item_bytes(data, pos, LAYOUT)
    if split is None:
        return None
    items, end = split
    return decode_items(items), end
