"""CAT048 (monoradar target reports) → plain values, with libasterix (edition 1.32).

Items used (LSBs from the CAT048 specification, as encoded in libasterix):

==========  ===========================================  =============================
item        content                                      kept as
==========  ===========================================  =============================
I048/010    SAC/SIC, data source                         ``sac``, ``sic``
I048/140    time of day, LSB 1/128 s                     ``tod`` (s since midnight UTC)
I048/020    target report descriptor: TYP, SIM, TST      ``typ``, ``sim``, ``tst``
I048/040    RHO LSB 1/256 NM, THETA LSB 360/2^16 deg     ``rho_nm``, ``theta_deg``
I048/020    … SPI (special position identification)      ``spi``
I048/070    Mode-3/A code (12 bits, octal digits), V,    ``mode_3a`` with
            G, L                                         ``mode_3a_not_validated``,
                                                         ``…_garbled``, ``…_smoothed``
I048/090    flight level, LSB 1/4 FL, V, G               ``flight_level`` with
                                                         ``flight_level_not_validated``,
                                                         ``…_garbled``
I048/130    plot characteristics: PAM, SAM (dBm)         ``amplitude_dbm`` (PAM, else SAM)
I048/220    Mode-S 24-bit aircraft address               ``mode_s``
I048/230    Mode S flight status STAT                    ``flight_status``
I048/240    aircraft identification, 8 × 6-bit ICAO      ``callsign`` (padding removed;
            characters                                   ``#`` for a code outside the set)
I048/250    Mode S BDS registers: MB data, BDS1, BDS2    ``registers`` ((MB, BDS1 << 4 |
                                                         BDS2), …), decoded by :mod:`.bds`
==========  ===========================================  =============================

Codes and levels are kept whatever their V/G/L flags (the flags travel with them); the
reader uses only validated, ungarbled flight levels as altitudes.

A record that parses but is not a usable plot (no I010/I140/I040, TYP 0 "no
detection", a time of day outside one day) is returned as a :class:`RecordReject`
with the reason, so the caller can count it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import asterix.generated as gen

from .layout import build_fspec, compile_layout, split_record
from .record_reject import RecordReject
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
    spi: bool = False
    mode_3a_not_validated: bool = False
    mode_3a_garbled: bool = False
    mode_3a_smoothed: bool = False
    flight_level_not_validated: bool = False
    flight_level_garbled: bool = False
    flight_status: int | None = None
    callsign: str | None = None
    registers: tuple[tuple[int, int], ...] = ()


ICAO_CHARS = "#ABCDEFGHIJKLMNOPQRSTUVWXYZ##### ###############0123456789######"
"""The ICAO 6-bit character set (I048/240, BDS 2,0); ``#``: a code outside it."""


def decode_callsign(raw: int) -> str | None:
    """The 8 characters of a 48-bit I048/240 value, trailing spaces removed (``None``
    for an all-space or all-zero value: no identification); a code outside the ICAO set
    gives ``#``."""
    if raw == 0:
        return None
    text = "".join(ICAO_CHARS[(raw >> (42 - 6 * i)) & 0x3F] for i in range(8)).rstrip()
    return text or None


def encode_callsign(text: str) -> int:
    """The 48-bit I048/240 value of a callsign (padded with spaces to 8 characters)."""
    if len(text) > 8:
        raise ValueError(f"callsign {text!r} is longer than 8 characters")
    raw = 0
    for ch in text.ljust(8):
        code = ICAO_CHARS.find(ch) if ch != "#" else -1
        if code < 0:
            raise ValueError(f"callsign {text!r}: {ch!r} is not an ICAO character")
        raw = raw << 6 | code
    return raw


def decode_record(rec: Any) -> Cat048Plot | RecordReject:
    """Physical values of one parsed CAT048 record (libasterix ``Record``)."""
    i010 = rec.get_item("010")
    if i010 is None:
        return RecordReject("cat048_no_data_source", "record has no I048/010 (SAC/SIC)")
    sac = sub_uint(i010.variation, "SAC")
    sic = sub_uint(i010.variation, "SIC")
    tod = quantity(rec, "140", "s")
    if tod is None:
        return RecordReject("cat048_no_time", "record has no I048/140 time of day", sac, sic)
    if not 0.0 <= tod < DAY_S + 1.0:
        return RecordReject(
            "cat048_bad_time", f"I048/140 time of day = {tod} s is outside one day", sac, sic
        )
    typ, sim, tst, spi = 0, False, False, False
    i020 = rec.get_item("020")
    if i020 is not None:
        v = i020.variation
        typ = sub_uint(v, "TYP")
        sim = bool(sub_uint(v, "SIM"))
        spi = bool(sub_uint(v, "SPI"))
        t = v.get_item("TST")
        tst = bool(t.as_uint()) if t is not None else False
        if typ == 0:
            return RecordReject("cat048_no_detection", "I048/020 TYP = 0 (no detection)", sac, sic)
    i040 = rec.get_item("040")
    if i040 is None:
        return RecordReject(
            "cat048_no_position", "record has no I048/040 measured position", sac, sic
        )
    rho = sub_quantity(i040.variation, "RHO", "NM")
    theta = sub_quantity(i040.variation, "THETA", "°")
    i220 = rec.get_item("220")
    addr = i220.as_uint() if i220 is not None else None
    amp = None
    i130 = rec.get_item("130")
    if i130 is not None:
        v = i130.variation
        for name in ("PAM", "SAM"):
            sub = v.get_item(name)
            if sub is not None:
                amp = sub.variation.content.as_quantity("dBm")
                break
    plot = Cat048Plot(sac, sic, tod, rho, theta, typ, sim, tst, None, None, addr, amp, spi=spi)
    _secondary_record(rec, plot)
    return plot


def _secondary_record(rec: Any, plot: Cat048Plot) -> None:
    """I070, I090, I230, I240 and I250 of a libasterix record into ``plot``."""
    i090 = rec.get_item("090")
    if i090 is not None:
        v = i090.variation
        plot.flight_level = sub_quantity(v, "FL", "FL")
        plot.flight_level_not_validated = bool(sub_uint(v, "V"))
        plot.flight_level_garbled = bool(sub_uint(v, "G"))
    i070 = rec.get_item("070")
    if i070 is not None:
        v = i070.variation
        plot.mode_3a = sub_uint(v, "MODE3A")
        plot.mode_3a_not_validated = bool(sub_uint(v, "V"))
        plot.mode_3a_garbled = bool(sub_uint(v, "G"))
        plot.mode_3a_smoothed = bool(sub_uint(v, "L"))
    i230 = rec.get_item("230")
    if i230 is not None:
        plot.flight_status = sub_uint(i230.variation, "STAT")
    i240 = rec.get_item("240")
    if i240 is not None:
        plot.callsign = decode_callsign(i240.as_uint())
    i250 = rec.get_item("250")
    if i250 is not None:
        plot.registers = tuple(
            (e.get_item("MBDATA").as_uint(),
             e.get_item("BDS1").as_uint() << 4 | e.get_item("BDS2").as_uint())
            for e in i250.variation.get_list()
        )  # fmt: skip


def _raw_items(
    *,
    sac: int,
    sic: int,
    tod: float,
    rho_nm: float,
    theta_deg: float,
    typ: int,
    sim: bool = False,
    spi: bool = False,
    flight_level: float | None = None,
    mode_3a: int | None = None,
    mode_s: int | None = None,
    amplitude_dbm: float | None = None,
    **secondary: Any,
) -> dict[str, Any]:
    """Raw (LSB-count) values of the items, rounded and range-checked, in UAP order."""
    rho_raw = round(rho_nm * 256.0)
    if not 0 <= rho_raw <= 0xFFFF:
        raise ValueError(f"RHO = {rho_nm} NM is outside I048/040 (0 .. 256 NM)")
    if not (0 <= sac <= 255 and 0 <= sic <= 255 and 0 <= typ <= 7):
        raise ValueError(f"SAC/SIC/TYP = {sac}/{sic}/{typ}: must be 0..255 / 0..255 / 0..7")
    raw: dict[str, Any] = {
        "010": (sac, sic),
        "140": round(tod * 128.0) % TOD_WRAP,
        "020": (typ, int(bool(sim)), int(bool(spi))),
        "040": (rho_raw, round(theta_deg * 65536.0 / 360.0) % 65536),
    }
    flag = secondary.get
    if mode_3a is not None:
        if not 0 <= int(mode_3a) <= 0o7777:
            raise ValueError(f"Mode-3/A code {mode_3a} is outside 0..4095 (octal 7777)")
        raw["070"] = (bool(flag("mode_3a_not_validated")) << 15
                      | bool(flag("mode_3a_garbled")) << 14
                      | bool(flag("mode_3a_smoothed")) << 13 | int(mode_3a))  # fmt: skip
    if flight_level is not None:
        fl_raw = round(flight_level * 4.0)
        if not -8192 <= fl_raw <= 8191:
            raise ValueError(f"flight level {flight_level} FL is outside I048/090 (±2048 FL)")
        raw["090"] = (bool(flag("flight_level_not_validated")) << 15
                      | bool(flag("flight_level_garbled")) << 14 | fl_raw & 0x3FFF)  # fmt: skip
    if amplitude_dbm is not None:
        raw["130"] = max(-128, min(127, round(amplitude_dbm))) & 0xFF
    if mode_s is not None:
        if not 0 <= int(mode_s) <= 0xFFFFFF:
            raise ValueError(f"Mode-S address {mode_s} is outside 24 bits")
        raw["220"] = int(mode_s)
    _raw_mode_s_items(raw, **secondary)
    return raw


_SECONDARY_FLAGS = frozenset(("mode_3a_not_validated", "mode_3a_garbled", "mode_3a_smoothed",
                              "flight_level_not_validated", "flight_level_garbled"))  # fmt: skip


def _raw_mode_s_items(
    raw: dict[str, Any],
    *,
    callsign: str | None = None,
    registers: tuple[tuple[int, int], ...] | list = (),
    flight_status: int | None = None,
    **flags: Any,
) -> None:
    """I240, I250 and I230 (in UAP order after I220) into ``raw``."""
    unknown = set(flags) - _SECONDARY_FLAGS
    if unknown:
        raise TypeError(f"unknown CAT048 value {sorted(unknown)[0]!r}")
    if callsign is not None:
        raw["240"] = encode_callsign(callsign)
    if registers:
        if len(registers) > 255:
            raise ValueError(f"{len(registers)} BDS registers: I048/250 holds at most 255")
        for mb, code in registers:
            if not (0 <= mb < 1 << 56 and 0 <= code <= 0xFF):
                raise ValueError(f"BDS register ({mb:#x}, {code:#x}): MB is 56 bits, BDS 8")
        raw["250"] = tuple((int(mb), int(code)) for mb, code in registers)
    if flight_status is not None:
        if not 0 <= flight_status <= 7:
            raise ValueError(f"flight status {flight_status} is outside I048/230 STAT (0..7)")
        raw["230"] = flight_status << 10


def build_record(**values: Any) -> Any:
    """A libasterix CAT048 record from physical values (keyword arguments as for
    :func:`encode_record`), each rounded to its item's LSB (time of day wraps at
    midnight, THETA at 360°). Raises ``ValueError`` naming a value that does not fit."""
    raw = _raw_items(**values)
    typ, sim, spi = raw["020"]
    items: dict[str, Any] = {
        "010": (("SAC", raw["010"][0]), ("SIC", raw["010"][1])),
        "140": raw["140"],
        "020": ((typ, sim, 0, spi, 0, None),),
        "040": (("RHO", raw["040"][0]), ("THETA", raw["040"][1])),
    }
    if "070" in raw:
        r = raw["070"]
        items["070"] = (r >> 15, r >> 14 & 1, r >> 13 & 1, 0, ("MODE3A", r & 0x0FFF))
    if "090" in raw:
        r = raw["090"]
        items["090"] = (r >> 15, r >> 14 & 1, ("FL", r & 0x3FFF))
    if "130" in raw:
        items["130"] = {"PAM": raw["130"]}
    for name in ("220", "240", "230"):
        if name in raw:
            items[name] = raw[name]
    if "250" in raw:
        items["250"] = [(("MBDATA", mb), ("BDS1", code >> 4), ("BDS2", code & 0xF))
                        for mb, code in raw["250"]]  # fmt: skip
    return SPEC.cv_record.create(items)


def encode_record(**values: Any) -> bytes:
    """The bytes of one CAT048 record (I010, I140, I020, I040, and I070, I090, I130 PAM,
    I220, I240, I250, I230 when given), identical to ``build_record(...).unparse()``
    (differential test) but packed directly: ~20× faster than building libasterix
    objects. Keywords: ``sac``, ``sic``, ``tod`` (s of day), ``rho_nm``, ``theta_deg``,
    ``typ`` (I020 TYP), and optional ``sim``, ``spi``, ``flight_level`` (FL),
    ``mode_3a``, ``mode_s``, ``amplitude_dbm``, the flags ``mode_3a_not_validated``,
    ``mode_3a_garbled``, ``mode_3a_smoothed``, ``flight_level_not_validated``,
    ``flight_level_garbled``, ``callsign``, ``registers`` ((MB, BDS1 << 4 | BDS2), …)
    and ``flight_status`` (see :func:`_raw_items`, which checks them)."""
    raw = _raw_items(**values)
    body = bytearray(raw["010"])
    body += raw["140"].to_bytes(3, "big")
    typ, sim, spi = raw["020"]
    body.append(typ << 5 | sim << 4 | spi << 2)
    body += raw["040"][0].to_bytes(2, "big") + raw["040"][1].to_bytes(2, "big")
    if "070" in raw:
        body += raw["070"].to_bytes(2, "big")
    if "090" in raw:
        body += raw["090"].to_bytes(2, "big")
    if "130" in raw:
        body += bytes((0x08, raw["130"]))  # compound FSPEC: 5th subitem (PAM)
    if "220" in raw:
        body += raw["220"].to_bytes(3, "big")
    if "240" in raw:
        body += raw["240"].to_bytes(6, "big")
    if "250" in raw:
        body.append(len(raw["250"]))
        for mb, code in raw["250"]:
            body += mb.to_bytes(7, "big") + bytes((code,))
    if "230" in raw:
        body += raw["230"].to_bytes(2, "big")
    return build_fspec(LAYOUT, list(raw)) + bytes(body)


def decode_fast(data: bytes, pos: int) -> tuple[Cat048Plot | RecordReject, int] | None:
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
        return RecordReject("cat048_no_data_source", "record has no I048/010 (SAC/SIC)"), end
    sac, sic = data[span[0]], data[span[0] + 1]
    span = items.get("140")
    if span is None:
        return RecordReject("cat048_no_time", "record has no I048/140 time of day", sac, sic), end
    tod = int.from_bytes(data[span[0] : span[1]], "big") / 128.0
    if not 0.0 <= tod < DAY_S + 1.0:
        reason = f"I048/140 time of day = {tod} s is outside one day"
        return RecordReject("cat048_bad_time", reason, sac, sic), end
    typ, sim, tst, spi = 0, False, False, False
    span = items.get("020")
    if span is not None:
        b0 = data[span[0]]
        typ, sim, spi = b0 >> 5, bool(b0 & 0x10), bool(b0 & 0x04)
        if span[1] - span[0] >= 2:
            tst = bool(data[span[0] + 1] & 0x80)
        if typ == 0:
            reason = "I048/020 TYP = 0 (no detection)"
            return RecordReject("cat048_no_detection", reason, sac, sic), end
    span = items.get("040")
    if span is None:
        reason = "record has no I048/040 measured position"
        return RecordReject("cat048_no_position", reason, sac, sic), end
    s0 = span[0]
    rho = int.from_bytes(data[s0 : s0 + 2], "big") / 256.0
    theta = int.from_bytes(data[s0 + 2 : s0 + 4], "big") * (360.0 / 65536.0)
    span = items.get("220")
    addr = int.from_bytes(data[span[0] : span[1]], "big") if span is not None else None
    span = items.get("130")
    amp = _amplitude_130(data, span[0]) if span is not None else None
    plot = Cat048Plot(sac, sic, tod, rho, theta, typ, sim, tst, None, None, addr, amp, spi=spi)
    _secondary_fast(data, items, plot)
    return plot, end


def _secondary_fast(data: bytes, items: dict[str, tuple[int, int]], plot: Cat048Plot) -> None:
    """I070, I090, I230, I240 and I250 from their byte spans into ``plot``."""
    span = items.get("090")
    if span is not None:
        raw = int.from_bytes(data[span[0] : span[1]], "big")
        v = raw & 0x3FFF
        plot.flight_level = (v - 0x4000 if v & 0x2000 else v) * 0.25
        plot.flight_level_not_validated = bool(raw & 0x8000)
        plot.flight_level_garbled = bool(raw & 0x4000)
    span = items.get("070")
    if span is not None:
        raw = int.from_bytes(data[span[0] : span[1]], "big")
        plot.mode_3a = raw & 0x0FFF
        plot.mode_3a_not_validated = bool(raw & 0x8000)
        plot.mode_3a_garbled = bool(raw & 0x4000)
        plot.mode_3a_smoothed = bool(raw & 0x2000)
    span = items.get("230")
    if span is not None:
        plot.flight_status = data[span[0]] >> 2 & 0x07
    span = items.get("240")
    if span is not None:
        plot.callsign = decode_callsign(int.from_bytes(data[span[0] : span[1]], "big"))
    span = items.get("250")
    if span is not None:
        s0 = span[0] + 1
        plot.registers = tuple(
            (int.from_bytes(data[p : p + 7], "big"), data[p + 7]) for p in range(s0, span[1], 8)
        )


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
