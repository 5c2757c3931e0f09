"""Mode S Comm-B registers (ASTERIX I048/250) → downlinked aircraft parameters.

A Mode S radar extracts registers of the aircraft's transponder (ICAO Doc 9871) and
reports each as its 56-bit MB field with the register number BDS1/BDS2 (I048/250,
"BDS register data"). The registers decoded here, with `pyModeS
<https://github.com/junzis/pyModeS>`_ 3.x, are the enhanced-surveillance ones:

==========  ====================================  ==========================================
register    content                               parameters (:mod:`schemas.identity`, SI/FL)
==========  ====================================  ==========================================
BDS 2,0     aircraft identification               ``callsign``
BDS 4,0     selected vertical intention           ``selected_altitude_mcp``, ``…_fms`` (FL)
BDS 5,0     track and turn report                 ``roll_angle``, ``true_track``,
                                                  ``ground_speed``, ``track_angle_rate``,
                                                  ``true_airspeed``
BDS 6,0     heading and speed report              ``magnetic_heading``, ``indicated_airspeed``,
                                                  ``mach``, ``baro_vertical_rate``,
                                                  ``inertial_vertical_rate``
==========  ====================================  ==========================================

A register with its number given (BDS1/BDS2 ≠ 0,0) is decoded with that register's
decoder (``pyModeS.decoder.bds.bdsXX.decode_bdsXX``: only the fields whose status bit is
set). A register reported as 0,0 (number unknown) goes through pyModeS's inference
(``pyModeS.decode(payload=..., df=20, icao=...)``): it is used when exactly one register
is plausible, otherwise counted as ambiguous. Other registers (1,0, 1,7, 3,0, …) are
counted and not used.

**Licence.** pyModeS is GPL-3.0 and skyfuse Apache-2.0, so pyModeS is an optional extra
(``pip install skyfuse[modes]``), imported lazily here and nowhere else. Without it the
registers are not decoded and each is counted as ``bds_not_decoded_no_pymodes``; every
other field of the plot is still read.

Units: pyModeS gives ft, degrees, kt, deg/s and ft/min; they are converted with
1 ft = 0.3048 m, 1 kt = 1852/3600 m/s (selected altitudes: ft / 100 → FL).

:func:`encode_register` is the inverse for the simulator and the CAT048 writer (bit
layouts of Doc 9871 tables A-2-32, A-2-48, A-2-96: BDS 4,0, 5,0, 6,0), so that a
written register decodes back through pyModeS (tested against pyModeS itself).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable
from typing import Any

from skyfuse.schemas.identity import DOWNLINK_REGISTERS, FT_PER_MIN, KT

TWO_PI = 2.0 * math.pi
USED = frozenset(("2,0", *DOWNLINK_REGISTERS))
"""The registers whose content a plot carries."""


@functools.cache
def _load() -> Any | None:
    """The pyModeS modules used (``None`` when pyModeS is not installed)."""
    try:
        import pyModeS
        from pyModeS.decoder.bds import bds20, bds40, bds50, bds60
    except ImportError:
        return None
    return pyModeS, {"2,0": bds20.decode_bds20, "4,0": bds40.decode_bds40,
                     "5,0": bds50.decode_bds50, "6,0": bds60.decode_bds60}  # fmt: skip


def available() -> bool:
    """Whether pyModeS is installed (the registers can be decoded)."""
    return _load() is not None


def register_name(code: int) -> str:
    """``"4,0"`` for the I048/250 BDS1/BDS2 byte 0x40."""
    return f"{code >> 4:X},{code & 0xF:X}"


def _si(raw: dict[str, Any]) -> dict[str, Any]:
    """pyModeS field names and units → skyfuse names and units."""
    out: dict[str, Any] = {}
    for key, value in raw.items():
        if key == "callsign":
            if value:
                out["callsign"] = value
        elif key in ("selected_altitude_mcp", "selected_altitude_fms"):
            out[key] = value / 100.0
        elif key == "roll":
            out["roll_angle"] = math.radians(value)
        elif key in ("true_track", "magnetic_heading"):
            angle = math.radians(value) % TWO_PI
            out[key] = 0.0 if angle >= TWO_PI else angle
        elif key in ("groundspeed", "true_airspeed", "indicated_airspeed"):
            out["ground_speed" if key == "groundspeed" else key] = value * KT
        elif key == "track_rate":
            out["track_angle_rate"] = math.radians(value)
        elif key == "mach":
            out["mach"] = float(value)
        elif key in ("baro_vertical_rate", "inertial_vertical_rate"):
            out[key] = value * FT_PER_MIN
    return out


def decode_registers(
    registers: Iterable[tuple[int, int]], address: int | None = None
) -> tuple[dict[str, Any], list[str]]:
    """Decode I048/250 elements ``(MB as a 56-bit int, BDS1 << 4 | BDS2)``.

    Returns the parameters (column name → value, SI/FL) and the count keys of what
    happened to each register (``bds_decoded_4_0``, ``bds_inferred_5_0``,
    ``bds_ambiguous``, ``bds_not_recognised``, ``bds_register_not_used``,
    ``bds_not_decoded_no_pymodes``). ``address``: the Mode-S address, for the inference
    of unnumbered registers (pyModeS wants one; 0 when unknown). Never raises."""
    values: dict[str, Any] = {}
    counts: list[str] = []
    modes = _load()
    for mb, code in registers:
        if modes is None:
            counts.append("bds_not_decoded_no_pymodes")
            continue
        name = register_name(code)
        if code == 0:
            name = _infer(modes[0], mb, address, counts)
            if name is None:
                continue
        elif name not in USED:
            counts.append("bds_register_not_used")
            continue
        else:
            counts.append(f"bds_decoded_{name.replace(',', '_')}")
        try:
            values.update(_si(modes[1][name](mb)))
        except Exception:  # a decoder bug must not lose the plot
            counts.append("bds_decoder_error")
    return values, counts


def _infer(pms: Any, mb: int, address: int | None, counts: list[str]) -> str | None:
    """The register of an unnumbered MB field by pyModeS's inference, or ``None``."""
    try:
        result = pms.decode(payload=f"{mb:014X}", df=20, icao=f"{address or 0:06X}")
    except Exception:
        counts.append("bds_not_recognised")
        return None
    best = result.get("bds")
    if best is None:
        counts.append("bds_not_recognised")
        return None
    if len(result.get("bds_candidates", [best])) > 1:
        counts.append("bds_ambiguous")
        return None
    if best not in USED:
        counts.append("bds_register_not_used")
        return None
    counts.append(f"bds_inferred_{best.replace(',', '_')}")
    return best


# ------------------------------------------------------------------- encoding
def _field(payload: int, status_bit: int, width: int, raw: int) -> int:
    """Set a status bit and the ``width``-bit raw value that follows it."""
    shift = 55 - (status_bit + width)
    return payload | 1 << (55 - status_bit) | (raw & ((1 << width) - 1)) << shift


def _signed_raw(value: float, lsb: float, bits: int) -> int:
    """Sign + ``bits``-bit magnitude in two's complement over ``bits + 1`` bits."""
    lim = 1 << bits
    return min(max(round(value / lsb), -lim), lim - 1) & ((lim << 1) - 1)


def _angle_raw(deg: float, lsb: float, bits: int) -> int:
    """An angle over ``bits`` bits (sign included) that span exactly 360°: wraps."""
    return round(deg / lsb) % (1 << bits)


def _unsigned_raw(value: float, lsb: float, bits: int) -> int:
    return min(max(round(value / lsb), 0), (1 << bits) - 1)


def encode_register(name: str, values: dict[str, float | None]) -> int | None:
    """The MB field of register ``name`` ("4,0", "5,0", "6,0") carrying the parameters
    of ``values`` (skyfuse names and units; a missing or None value leaves its status
    bit clear), or ``None`` when none of its parameters is given. Values are rounded to
    the register's LSB and clipped to its range."""

    def have(key: str) -> bool:
        return values.get(key) is not None

    p = 0
    if name == "4,0":
        for bit, key in ((0, "selected_altitude_mcp"), (13, "selected_altitude_fms")):
            if have(key):
                p = _field(p, bit, 12, _unsigned_raw(values[key] * 100.0, 16.0, 12))
    elif name == "5,0":
        deg, kt = math.degrees, 1.0 / KT
        if have("roll_angle"):
            p = _field(p, 0, 10, _signed_raw(deg(values["roll_angle"]), 45.0 / 256, 9))
        if have("true_track"):
            p = _field(p, 11, 11, _angle_raw(deg(values["true_track"]), 90.0 / 512, 11))
        if have("ground_speed"):
            p = _field(p, 23, 10, _unsigned_raw(values["ground_speed"] * kt, 2.0, 10))
        if have("track_angle_rate"):
            p = _field(p, 34, 10, _signed_raw(deg(values["track_angle_rate"]), 8.0 / 256, 9))
        if have("true_airspeed"):
            p = _field(p, 45, 10, _unsigned_raw(values["true_airspeed"] * kt, 2.0, 10))
    elif name == "6,0":
        p = _encode_bds60(values, have)
    else:
        raise ValueError(f"register {name!r}: only 4,0, 5,0 and 6,0 are encoded")
    return p or None


def _encode_bds60(values: dict[str, float | None], have) -> int:
    p = 0
    if have("magnetic_heading"):
        p = _field(p, 0, 11, _angle_raw(math.degrees(values["magnetic_heading"]), 90.0 / 512, 11))
    if have("indicated_airspeed"):
        p = _field(p, 12, 10, _unsigned_raw(values["indicated_airspeed"] / KT, 1.0, 10))
    if have("mach"):
        p = _field(p, 23, 10, _unsigned_raw(values["mach"], 2.048 / 512, 10))
    for bit, key in ((34, "baro_vertical_rate"), (45, "inertial_vertical_rate")):
        if have(key):
            p = _field(p, bit, 10, _signed_raw(values[key] / FT_PER_MIN, 32.0, 9))
    return p
