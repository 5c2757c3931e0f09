"""CAT048 (monoradar target reports) → plain values, with libasterix (edition 1.32).

Items used (LSBs from the CAT048 specification, as encoded in libasterix):

==========  ===========================================  =============================
item        content                                      kept as
==========  ===========================================  =============================
I048/010    SAC/SIC, data source                         ``sac``, ``sic``
I048/140    time of day, LSB 1/128 s                     ``tod`` (s since midnight UTC)
I048/020    target report descriptor: TYP, SIM, TST      ``typ``, ``sim``, ``tst``
I048/040    RHO LSB 1/256 NM, THETA LSB 360/2^16 deg     ``rho_nm``, ``theta_deg``
I048/070    Mode-3/A code (12 bits, octal digits), V, G  ``mode_3a`` (validated only)
I048/090    flight level, LSB 1/4 FL, V, G               ``flight_level`` (validated)
I048/130    plot characteristics: PAM, SAM (dBm)         ``amplitude_dbm`` (PAM, else SAM)
I048/220    Mode-S 24-bit aircraft address               ``mode_s``
==========  ===========================================  =============================

A record that parses but is not a usable plot (no I010/I140/I040, TYP 0 "no
detection", a time of day outside one day) is returned as a :class:`Cat048Reject`
with the reason, so the caller can count it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import asterix.generated as gen

from .layout import build_fspec, compile_layout, split_record
from .records import quantity, sub_quantity, sub_uint

SPEC = gen.Cat_048_1_32
CATEGORY = 48
DAY_S = 86_400.0
TOD_WRAP = 86_400 * 128  # I048/140 counts of one day

#: I048/020 TYP values (plot type).
PLOT_TYPES = {
    0: "no detection",
    1: "single PSR detection",
    2: "single SSR detection",
    3: "SSR + PSR detection",
    4: "single Mode S all-call",
    5: "single Mode S roll-call",
    6: "Mode S all-call + PSR",
    7: "Mode S roll-call + PSR",
}


LAYOUT = compile_layout(SPEC)


@dataclass(slots=True)
class Cat048Plot:
    """One CAT048 target report in ASTERIX units (NM, degrees, FL, s of day)."""

    sac: int
    sic: int
    tod: float
    rho_nm: float
    theta_deg: float
    typ: int
    sim: bool
    tst: bool
    flight_level: float | None
    mode_3a: int | None
    mode_s: int | None
    amplitude_dbm: float | None


@dataclass(slots=True)
class Cat048Reject:
    """A parsed record that is not a usable plot; ``reason`` is a short count key."""

    reason: str
    detail: str
    sac: int | None = None
    sic: int | None = None


def decode_record(rec: Any) -> Cat048Plot | Cat048Reject:
    """Physical values of one parsed CAT048 record (libasterix ``Record``)."""
    i010 = rec.get_item("010")
    if i010 is None:
        return Cat048Reject("cat048_no_data_source", "record has no I048/010 (SAC/SIC)")
    sac = sub_uint(i010.variation, "SAC")
    sic = sub_uint(i010.variation, "SIC")
    tod = quantity(rec, "140", "s")
    if tod is None:
        return Cat048Reject("cat048_no_time", "record has no I048/140 time of day", sac, sic)
    if not 0.0 <= tod < DAY_S + 1.0:
        return Cat048Reject(
            "cat048_bad_time", f"I048/140 time of day = {tod} s is outside one day", sac, sic
        )
    typ, sim, tst = 0, False, False
    i020 = rec.get_item("020")
    if i020 is not None:
        v = i020.variation
        typ = sub_uint(v, "TYP")
        sim = bool(sub_uint(v, "SIM"))
        t = v.get_item("TST")
        tst = bool(t.as_uint()) if t is not None else False
        if typ == 0:
            return Cat048Reject("cat048_no_detection", "I048/020 TYP = 0 (no detection)", sac, sic)
    i040 = rec.get_item("040")
    if i040 is None:
        return Cat048Reject(
            "cat048_no_position", "record has no I048/040 measured position", sac, sic
        )
    rho = sub_quantity(i040.variation, "RHO", "NM")
    theta = sub_quantity(i040.variation, "THETA", "°")
    fl = None
    i090 = rec.get_item("090")
    if i090 is not None:
        v = i090.variation
        if sub_uint(v, "V") == 0 and sub_uint(v, "G") == 0:
            fl = sub_quantity(v, "FL", "FL")
    code = None
    i070 = rec.get_item("070")
    if i070 is not None:
        v = i070.variation
        if sub_uint(v, "V") == 0 and sub_uint(v, "G") == 0:
            code = sub_uint(v, "MODE3A")
    addr = None
    i220 = rec.get_item("220")
    if i220 is not None:
        addr = i220.as_uint()
    amp = None
    i130 = rec.get_item("130")
    if i130 is not None:
        v = i130.variation
        for name in ("PAM", "SAM"):
            sub = v.get_item(name)
            if sub is not None:
                amp = sub.variation.content.as_quantity("dBm")
                break
    return Cat048Plot(sac, sic, tod, rho, theta, typ, sim, tst, fl, code, addr, amp)


def _raw_items(
    *,
    sac: int,
    sic: int,
    tod: float,
    rho_nm: float,
    theta_deg: float,
    typ: int,
    sim: bool = False,
    flight_level: float | None = None,
    mode_3a: int | None = None,
    mode_s: int | None = None,
    amplitude_dbm: float | None = None,
) -> dict[str, Any]:
    """Raw (LSB-count) values of the items, rounded and range-checked."""
    rho_raw = round(rho_nm * 256.0)
    if not 0 <= rho_raw <= 0xFFFF:
        raise ValueError(f"RHO = {rho_nm} NM is outside I048/040 (0 .. 256 NM)")
    if not (0 <= sac <= 255 and 0 <= sic <= 255 and 0 <= typ <= 7):
        raise ValueError(f"SAC/SIC/TYP = {sac}/{sic}/{typ}: must be 0..255 / 0..255 / 0..7")
    raw: dict[str, Any] = {
        "010": (sac, sic),
        "140": round(tod * 128.0) % TOD_WRAP,
        "020": (typ, int(bool(sim))),
        "040": (rho_raw, round(theta_deg * 65536.0 / 360.0) % 65536),
    }
    if mode_3a is not None:
        if not 0 <= int(mode_3a) <= 0o7777:
            raise ValueError(f"Mode-3/A code {mode_3a} is outside 0..4095 (octal 7777)")
        raw["070"] = int(mode_3a)
    if flight_level is not None:
        fl_raw = round(flight_level * 4.0)
        if not -8192 <= fl_raw <= 8191:
            raise ValueError(f"flight level {flight_level} FL is outside I048/090 (±2048 FL)")
        raw["090"] = fl_raw & 0x3FFF
    if amplitude_dbm is not None:
        raw["130"] = max(-128, min(127, round(amplitude_dbm))) & 0xFF
    if mode_s is not None:
        if not 0 <= int(mode_s) <= 0xFFFFFF:
            raise ValueError(f"Mode-S address {mode_s} is outside 24 bits")
        raw["220"] = int(mode_s)
    return raw


def build_record(**values: Any) -> Any:
    """A libasterix CAT048 record from physical values (keyword arguments as for
    :func:`encode_record`), each rounded to its item's LSB (time of day wraps at
    midnight, THETA at 360°). Raises ``ValueError`` naming a value that does not fit."""
    raw = _raw_items(**values)
    items: dict[str, Any] = {
        "010": (("SAC", raw["010"][0]), ("SIC", raw["010"][1])),
        "140": raw["140"],
        "020": ((raw["020"][0], raw["020"][1], 0, 0, 0, None),),
        "040": (("RHO", raw["040"][0]), ("THETA", raw["040"][1])),
    }
    if "070" in raw:
        items["070"] = (0, 0, 0, 0, ("MODE3A", raw["070"]))
    if "090" in raw:
        items["090"] = (0, 0, ("FL", raw["090"]))
    if "130" in raw:
        items["130"] = {"PAM": raw["130"]}
    if "220" in raw:
        items["220"] = raw["220"]
    return SPEC.cv_record.create(items)


def encode_record(**values: Any) -> bytes:
    """The bytes of one CAT048 record (I010, I140, I020, I040, and I070, I090, I130 PAM,
    I220 when given), identical to ``build_record(...).unparse()`` (differential test)
    but packed directly: ~20× faster than building libasterix objects. Keywords: ``sac``,
    ``sic``, ``tod`` (s of day), ``rho_nm``, ``theta_deg``, ``typ`` (I020 TYP), and
    optional ``sim``, ``flight_level`` (FL), ``mode_3a``, ``mode_s``, ``amplitude_dbm``
    (see :func:`_raw_items`, which checks them)."""
    raw = _raw_items(**values)
    body = bytearray(raw["010"])
    body += raw["140"].to_bytes(3, "big")
    body.append(raw["020"][0] << 5 | raw["020"][1] << 4)
    body += raw["040"][0].to_bytes(2, "big") + raw["040"][1].to_bytes(2, "big")
    if "070" in raw:
        body += raw["070"].to_bytes(2, "big")
    if "090" in raw:
        body += raw["090"].to_bytes(2, "big")
    if "130" in raw:
        body += bytes((0x08, raw["130"]))  # compound FSPEC: 5th subitem (PAM)
    if "220" in raw:
        body += raw["220"].to_bytes(3, "big")
    return build_fspec(LAYOUT, list(raw)) + bytes(body)


def decode_fast(data: bytes, pos: int) -> tuple[Cat048Plot | Cat048Reject, int] | None:
    """Decode the record at ``pos`` without building libasterix objects.

    Returns ``(plot or reject, end offset)``, or ``None`` when the record is not
    well formed (or uses RFS): the caller then re-parses with libasterix, which gives
    the authoritative error. Values are identical to :func:`decode_record` (checked by
    a differential test); the LSBs are those of the CAT048 items listed above."""
    split = split_record(data, pos, LAYOUT)
    if isinstance(split, str):
        return None
    end, items = split
    span = items.get("010")
    if span is None:
        return Cat048Reject("cat048_no_data_source", "record has no I048/010 (SAC/SIC)"), end
    sac, sic = data[span[0]], data[span[0] + 1]
    span = items.get("140")
    if span is None:
        return Cat048Reject("cat048_no_time", "record has no I048/140 time of day", sac, sic), end
    tod = int.from_bytes(data[span[0] : span[1]], "big") / 128.0
    if not 0.0 <= tod < DAY_S + 1.0:
        reason = f"I048/140 time of day = {tod} s is outside one day"
        return Cat048Reject("cat048_bad_time", reason, sac, sic), end
    typ, sim, tst = 0, False, False
    span = items.get("020")
    if span is not None:
        b0 = data[span[0]]
        typ, sim = b0 >> 5, bool(b0 & 0x10)
        if span[1] - span[0] >= 2:
            tst = bool(data[span[0] + 1] & 0x80)
        if typ == 0:
            reason = "I048/020 TYP = 0 (no detection)"
            return Cat048Reject("cat048_no_detection", reason, sac, sic), end
    span = items.get("040")
    if span is None:
        reason = "record has no I048/040 measured position"
        return Cat048Reject("cat048_no_position", reason, sac, sic), end
    s0 = span[0]
    rho = int.from_bytes(data[s0 : s0 + 2], "big") / 256.0
    theta = int.from_bytes(data[s0 + 2 : s0 + 4], "big") * (360.0 / 65536.0)
    fl = None
    span = items.get("090")
    if span is not None:
        raw = int.from_bytes(data[span[0] : span[1]], "big")
        if not raw & 0xC000:  # V = 0, G = 0
            v = raw & 0x3FFF
            fl = (v - 0x4000 if v & 0x2000 else v) * 0.25
    code = None
    span = items.get("070")
    if span is not None:
        raw = int.from_bytes(data[span[0] : span[1]], "big")
        if not raw & 0xC000:
            code = raw & 0x0FFF
    addr = None
    span = items.get("220")
    if span is not None:
        addr = int.from_bytes(data[span[0] : span[1]], "big")
    amp = None
    span = items.get("130")
    if span is not None:
        amp = _amplitude_130(data, span[0])
    return Cat048Plot(sac, sic, tod, rho, theta, typ, sim, tst, fl, code, addr, amp), end


def _amplitude_130(data: bytes, pos: int) -> float | None:
    """PAM (else SAM) of I048/130: 1-byte FSPEC (SRL SRR SAM PRL PAM RPD APD), 1 byte each."""
    fspec = data[pos]
    present = [bool(fspec & (0x80 >> i)) for i in range(7)]
    offset = pos + 1
    values: dict[int, int] = {}
    for i, flag in enumerate(present):
        if flag:
            values[i] = data[offset]
            offset += 1
    for index in (4, 2):  # PAM, then SAM
        if index in values:
            v = values[index]
            return float(v - 256 if v & 0x80 else v)
    return None
