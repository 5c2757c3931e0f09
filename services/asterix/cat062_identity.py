"""The identity items of a CAT062 system track (edition 1.20): a track's identity,
downlinked parameters and their ages → raw item values, packed bytes, and the same
items built with libasterix (the reference encoder of the differential test).

==========  ==================================================  ===========================
item        content                                             from :class:`schemas.Track`
==========  ==================================================  ===========================
I062/060    Mode-3/A code (V = 0, G = 0: the fusion shows only  ``mode_3a``,
            validated ungarbled codes), CH = 1 while the code   ``mode_3a_changed``
            counts as changed
I062/245    target identification, STI = 0 (downlinked: every   ``callsign``
            callsign a track shows came from the aircraft's
            BDS 2,0 via the plots; none comes from a flight
            plan), 8 × 6-bit ICAO characters
I062/380    aircraft derived data: ADR (address), ID            ``mode_s``, ``callsign``,
            (identification), MHG (360/2¹⁶ °), IAS (IM = 0:     ``magnetic_heading``,
            2⁻¹⁴ NM/s; IM = 1: Mach 0.001, when only Mach is    ``indicated_airspeed`` /
            known), TAS (1 kt), SAL (selected altitude, 25 ft:  ``mach``,
            the FMS one, SRC = 3, else the MCP/FCU one, SRC =   ``true_airspeed``,
            2), FSS (final state selected altitude = MCP/FCU,   ``selected_altitude_*``,
            25 ft), BVR / GVR (6.25 ft/min: barometric rate;    ``baro_vertical_rate``,
            the inertial vertical velocity of BDS 6,0 as the    ``inertial_vertical_rate``,
            geometric rate), RAN (0.01 °), TAR (TI left/right/  ``roll_angle``,
            straight, ROT 1/4 °/s), TAN (track angle 360/2¹⁶    ``track_angle_rate``,
            °), GS (2⁻¹⁴ NM/s), MAC (Mach 0.008)                ``true_track``,
                                                                ``ground_speed``
I062/290    ages per technology (1/4 s, at most 63.75 s): PSR,  ``psr_time``, ``ssr_time``,
            SSR, MDS                                            ``mode_s_update_time``
I062/295    ages of the data (1/4 s, at most 63.75 s): MFL,     ``flight_level_time``,
            MDA, MHG, IAS, TAS, SAL, FSS, BVR, GVR, RAN, TAR,   ``mode_3a_time`` and the
            TAN, GSP, MAC                                       registers' times
I062/340    the last plot's measured information: SID (when     ``last_plot``
            its radar id is ``SAC-SIC``), POS (RHO 1/256 NM,
            THETA 360/2¹⁶ °), MDC (V, G, last Mode C 1/4 FL),
            MDA (V, G, L, code), TYP (I048 TYP)
==========  ==================================================  ===========================

Ages are ``track.time`` minus the time a value was last confirmed. A value outside its
item's range is clipped to it (counted by the writer). Items or subfields without a
value are left out, so a track without identity gives the same record as before.
"""

from __future__ import annotations

import math
from typing import Any

from skyfuse.schemas import Track
from skyfuse.schemas.identity import FT_PER_MIN, KT

from .cat048 import encode_callsign
from .layout import RecordLayout, build_fspec
from .sites import sac_sic_of

NM = 1852.0
LSB_ANGLE = 360.0 / 2**16  # deg
LSB_NM_S = 2.0**-14  # NM/s
AGE_LSB = 0.25  # s
AGE_MAX = 255

_KINEMATIC_FIELDS = frozenset(("track_id", "time", "status", "existence", "state",
                               "covariance", "lat", "lon", "alt", "vel_east", "vel_north",
                               "vel_up", "speed", "heading", "radars", "updates"))  # fmt: skip
I380_SLOTS = ("ADR", "ID", "MHG", "IAS", "TAS", "SAL", "FSS", "TIS", "TID", "COM", "SAB", "ACS",
              "BVR", "GVR", "RAN", "TAR", "TAN", "GS", "VUN", "MET", "EMC", "POS", "GAL", "PUN",
              "MB", "IAR", "MAC", "BPS")  # fmt: skip
I290_SLOTS = ("TRK", "PSR", "SSR", "MDS", "ADS", "ES", "VDL", "UAT", "LOP", "MLT")
I295_SLOTS = ("MFL", "MD1", "MD2", "MDA", "MD4", "MD5", "MHG", "IAS", "TAS", "SAL", "FSS", "TID",
              "COM", "SAB", "ACS", "BVR", "GVR", "RAN", "TAR", "TAN", "GSP", "VUN", "MET", "EMC",
              "POS", "GAL", "PUN", "MB", "IAR", "MAC", "BPS")  # fmt: skip
I340_SLOTS = ("SID", "POS", "HEIGHT", "MDC", "MDA", "TYP")
_LAYOUTS = {
    name: RecordLayout(fspec, tuple((s, None) for s in slots))
    for name, fspec, slots in (("380", 4, I380_SLOTS), ("290", 2, I290_SLOTS),
                               ("295", 5, I295_SLOTS), ("340", 1, I340_SLOTS))
}  # fmt: skip


def _raw(value: float, lsb: float, bits: int, signed: bool = False) -> tuple[int, bool]:
    """``value / lsb`` rounded, clipped to the field (two's complement when signed),
    and whether it had to be clipped."""
    lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
    r = round(value / lsb)
    clipped = min(max(r, lo), hi)
    return clipped & ((1 << bits) - 1), clipped != r


class _Fields:
    """Raw subfields being collected, with the count of clipped values."""

    def __init__(self) -> None:
        self.values: dict[str, Any] = {}
        self.clipped = 0

    def put(self, name: str, value: float | None, lsb: float, bits: int, signed=False) -> None:
        if value is not None:
            self.values[name], clipped = _raw(value, lsb, bits, signed)
            self.clipped += clipped


def _i380(t: Track) -> _Fields:
    f = _Fields()
    if t.mode_s is not None:
        f.values["ADR"] = t.mode_s
    if t.callsign is not None:
        f.values["ID"] = encode_callsign(t.callsign)
    f.put("MHG", _deg(t.magnetic_heading), LSB_ANGLE, 16)
    if t.indicated_airspeed is not None:
        f.put("IAS", t.indicated_airspeed / NM, LSB_NM_S, 15)
        f.values["IAS"] = (0, f.values["IAS"])
    elif t.mach is not None:
        f.put("IAS", t.mach, 0.001, 15)
        f.values["IAS"] = (1, f.values["IAS"])
    f.put("TAS", None if t.true_airspeed is None else t.true_airspeed / KT, 1.0, 16)
    sal, src = ((t.selected_altitude_fms, 3) if t.selected_altitude_fms is not None
                else (t.selected_altitude_mcp, 2))  # fmt: skip
    f.put("SAL", None if sal is None else sal * 100.0, 25.0, 13, signed=True)
    if "SAL" in f.values:
        f.values["SAL"] = (1, src, f.values["SAL"])
    f.put("FSS", _ft(t.selected_altitude_mcp), 25.0, 13, signed=True)
    if "FSS" in f.values:
        f.values["FSS"] = (0, 0, 0, f.values["FSS"])
    f.put("BVR", _fpm(t.baro_vertical_rate), 6.25, 16, signed=True)
    f.put("GVR", _fpm(t.inertial_vertical_rate), 6.25, 16, signed=True)
    f.put("RAN", _deg(t.roll_angle), 0.01, 16, signed=True)
    if t.track_angle_rate is not None:
        f.put("TAR", math.degrees(t.track_angle_rate), 0.25, 7, signed=True)
        rate = t.track_angle_rate
        f.values["TAR"] = (2 if rate > 0 else 1 if rate < 0 else 3, f.values["TAR"])
    f.put("TAN", _deg(t.true_track), LSB_ANGLE, 16)
    f.put("GS", None if t.ground_speed is None else t.ground_speed / NM, LSB_NM_S, 16, True)
    f.put("MAC", t.mach, 0.008, 16)
    return f


def _deg(rad: float | None) -> float | None:
    return None if rad is None else math.degrees(rad)


def _ft(fl: float | None) -> float | None:
    return None if fl is None else fl * 100.0


def _fpm(mps: float | None) -> float | None:
    return None if mps is None else mps / FT_PER_MIN


def _ages(t: Track, pairs) -> dict[str, int]:
    """Ages (1/4 s, clipped to 63.75 s) of the (subfield, time) pairs with a time."""
    out = {}
    for name, when in pairs:
        if when is not None:
            out[name] = min(max(round((t.time - when) * 1e-9 / AGE_LSB), 0), AGE_MAX)
    return out


def _i295(t: Track) -> dict[str, int]:
    """The ages of the values the track shows (each value's time, or its register's)."""
    shown = [("MFL", t.flight_level, t.flight_level_time), ("MDA", t.mode_3a, t.mode_3a_time)]
    reg = {"MHG": ("magnetic_heading", t.heading_speed_time),
           "IAS": ("indicated_airspeed", t.heading_speed_time),
           "TAS": ("true_airspeed", t.track_turn_time),
           "SAL": ("selected_altitude_mcp", t.intention_time),
           "FSS": ("selected_altitude_mcp", t.intention_time),
           "BVR": ("baro_vertical_rate", t.heading_speed_time),
           "GVR": ("inertial_vertical_rate", t.heading_speed_time),
           "RAN": ("roll_angle", t.track_turn_time), "TAR": ("track_angle_rate", t.track_turn_time),
           "TAN": ("true_track", t.track_turn_time), "GSP": ("ground_speed", t.track_turn_time),
           "MAC": ("mach", t.heading_speed_time)}  # fmt: skip
    for name, (field, when) in reg.items():
        value = getattr(t, field)
        if name == "SAL" and value is None:
            value = t.selected_altitude_fms
        if name == "IAS" and value is None:
            value = t.mach
        shown.append((name, value, when))
    return _ages(t, [(name, when) for name, value, when in shown if value is not None])


def _i340(t: Track) -> dict[str, Any]:
    p = t.last_plot
    out: dict[str, Any] = {}
    if p is None:
        return out
    try:
        out["SID"] = sac_sic_of(p.radar_id)
    except ValueError:
        pass
    if p.range is not None and p.azimuth is not None:
        rho, _ = _raw(p.range / NM, 1 / 256, 16)
        out["POS"] = (rho, round(math.degrees(p.azimuth) / LSB_ANGLE) % 65536)
    if p.flight_level is not None:
        level, _ = _raw(p.flight_level, 0.25, 14, signed=True)
        out["MDC"] = (int(p.flight_level_not_validated), int(p.flight_level_garbled), level)
    if p.mode_3a is not None:
        out["MDA"] = (int(p.mode_3a_not_validated), int(p.mode_3a_garbled),
                      int(p.mode_3a_smoothed), p.mode_3a)  # fmt: skip
    if p.plot_type is not None:
        out["TYP"] = p.plot_type
    return out


_IDENTITY_FIELDS = frozenset(
    name for name in Track.model_fields if name not in _KINEMATIC_FIELDS
)  # fmt: skip


def identity_items(t: Track) -> tuple[dict[str, Any], int]:
    """Raw values of I060, I245, I380, I290, I295 and I340 for ``t`` (only those with
    content) and the number of values clipped to their field."""
    if _IDENTITY_FIELDS.isdisjoint(t.model_fields_set):
        return {}, 0  # a track made without identity fields: nothing to look at
    raw: dict[str, Any] = {}
    if t.mode_3a is not None:
        raw["060"] = (int(bool(t.mode_3a_changed)), t.mode_3a)
    if t.callsign is not None:
        raw["245"] = encode_callsign(t.callsign)
    f = _i380(t)
    if f.values:
        raw["380"] = f.values
    ages = _ages(t, (("PSR", t.psr_time), ("SSR", t.ssr_time), ("MDS", t.mode_s_update_time)))
    if ages:
        raw["290"] = ages
    ages = _i295(t)
    if ages:
        raw["295"] = ages
    last = _i340(t)
    if last:
        raw["340"] = last
    return raw, f.clipped


# ------------------------------------------------------------------ packing
def _pack_380(v: dict[str, Any]) -> bytes:
    out = bytearray(build_fspec(_LAYOUTS["380"], [s for s in I380_SLOTS if s in v]))
    for name in I380_SLOTS:
        if name not in v:
            continue
        x = v[name]
        if name == "ADR":
            out += x.to_bytes(3, "big")
        elif name == "ID":
            out += x.to_bytes(6, "big")
        elif name == "IAS":
            out += (x[0] << 15 | x[1]).to_bytes(2, "big")
        elif name == "SAL":
            out += (x[0] << 15 | x[1] << 13 | x[2]).to_bytes(2, "big")
        elif name == "FSS":
            out += (x[0] << 15 | x[1] << 14 | x[2] << 13 | x[3]).to_bytes(2, "big")
        elif name == "TAR":
            out += bytes((x[0] << 6, x[1] << 1))
        else:
            out += x.to_bytes(2, "big")
    return bytes(out)


def _pack_ages(name: str, v: dict[str, int]) -> bytes:
    slots = I290_SLOTS if name == "290" else I295_SLOTS
    present = [s for s in slots if s in v]
    return build_fspec(_LAYOUTS[name], present) + bytes(v[s] for s in present)


def _pack_340(v: dict[str, Any]) -> bytes:
    out = bytearray(build_fspec(_LAYOUTS["340"], [s for s in I340_SLOTS if s in v]))
    if "SID" in v:
        out += bytes(v["SID"])
    if "POS" in v:
        out += v["POS"][0].to_bytes(2, "big") + v["POS"][1].to_bytes(2, "big")
    if "MDC" in v:
        g_v, g_g, level = v["MDC"]
        out += (g_v << 15 | g_g << 14 | level).to_bytes(2, "big")
    if "MDA" in v:
        m_v, m_g, m_l, code = v["MDA"]
        out += (m_v << 15 | m_g << 14 | m_l << 13 | code).to_bytes(2, "big")
    if "TYP" in v:
        out.append(v["TYP"] << 5)
    return bytes(out)


def pack_identity(name: str, value: Any) -> bytes:
    """The bytes of identity item ``name`` from its raw value."""
    if name == "060":
        return (value[0] << 13 | value[1]).to_bytes(2, "big")  # V = G = 0, CH, spare
    if name == "245":
        return value.to_bytes(7, "big")  # STI = 0 in the top two bits
    if name == "380":
        return _pack_380(value)
    if name in ("290", "295"):
        return _pack_ages(name, value)
    return _pack_340(value)


def build_identity(name: str, value: Any) -> Any:
    """The libasterix ``create`` argument of identity item ``name`` (reference encoder)."""
    if name == "060":
        return (0, 0, ("CH", value[0]), 0, ("MODE3A", value[1]))
    if name == "245":
        return (0, 0, ("CHR", value))
    if name in ("290", "295"):
        return dict(value)
    if name == "340":
        out: dict[str, Any] = {}
        for sub, x in value.items():
            out[sub] = {"SID": lambda x: (("SAC", x[0]), ("SIC", x[1])),
                        "POS": lambda x: (("RHO", x[0]), ("THETA", x[1])),
                        "MDC": lambda x: (x[0], x[1], ("LMC", x[2])),
                        "MDA": lambda x: (x[0], x[1], x[2], 0, ("MODE3A", x[3])),
                        "TYP": lambda x: (x, 0, 0, 0, 0)}[sub](x)  # fmt: skip
        return out
    out = {}
    for sub, x in value.items():
        if sub == "IAS":
            out[sub] = (x[0], ("IAS", x[1]))
        elif sub == "SAL":
            out[sub] = (x[0], x[1], ("ALT", x[2]))
        elif sub == "FSS":
            out[sub] = (x[0], x[1], x[2], ("ALT", x[3]))
        elif sub == "TAR":
            out[sub] = (x[0], 0, ("ROT", x[1]), 0)
        else:
            out[sub] = x
    return out
