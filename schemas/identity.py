"""Secondary-surveillance attributes: who an aircraft is and what it says about itself.

One vocabulary for the plot columns of :class:`~skyfuse.schemas.PlotBatch` and the
fields of :class:`~skyfuse.schemas.Track`: the same names, units and bounds on both
(a plot carries the value of one reply, a track the value it currently shows).

Units: SI (m/s, rad, rad/s) like every other skyfuse quantity, except the *pressure
altitudes* — the flight level (Mode C, ASTERIX I048/090, I062/136) and the selected
altitudes (BDS 4,0) — which stay in **FL** (hundreds of feet of ISA pressure altitude):
they are barometric readings, not heights, and FL is the unit they are reported,
displayed and cleared in (a selected altitude of 33,008 ft is FL 330.08). The plot's
``altitude`` column (m) is the *geometric* use of the flight level (see
``services/asterix/reader.py``).

Identity (per reply):

* ``mode_3a``: the Mode-3/A code as the integer of its 12 bits (octal 7777 → 4095),
  with ``mode_3a_not_validated`` / ``mode_3a_garbled`` / ``mode_3a_smoothed`` (ASTERIX
  I048/070 V, G and L: the code was not validated, was garbled, or was not extracted in
  this scan but kept from the previous one);
* ``mode_s``: the 24-bit ICAO aircraft address;
* ``callsign``: the aircraft identification (BDS 2,0, I048/240), at most 8 characters
  of ``A-Z``, ``0-9`` and inner spaces, trailing spaces removed;
* ``flight_level`` (FL) with ``flight_level_not_validated`` / ``flight_level_garbled``
  (I048/090 V, G);
* ``spi``: the special position identification pulse (I048/020 SPI);
* ``flight_status``: the Mode S flight status FS (I048/230 STAT): 0 airborne, 1 on the
  ground, 2 alert airborne, 3 alert on the ground, 4 alert and SPI, 5 SPI, 7 unknown.

Downlinked aircraft parameters (Mode S enhanced surveillance, ICAO Doc 9871 registers,
decoded by pyModeS: ``services/asterix/bds.py``): :data:`DOWNLINKED`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from enum import StrEnum

KT = 1852.0 / 3600.0
"""One knot in m/s."""
FT_PER_MIN = 0.3048 / 60.0
"""One foot per minute in m/s."""

CALLSIGN_PATTERN = r"^[A-Z0-9](?:[A-Z0-9 ]{0,6}[A-Z0-9])?$"
"""A callsign as carried: 1-8 characters of the ICAO 6-bit set without the padding."""
CALLSIGN_RE = re.compile(CALLSIGN_PATTERN)

MODE_3A_MAX = 0o7777
MODE_S_MAX = 0xFFFFFF
FLIGHT_STATUS_MAX = 7
FLIGHT_LEVEL_MIN, FLIGHT_LEVEL_MAX = -2048.0, 2048.0
"""I048/090 and I062/136 hold ±2048 FL (14 and 16 bits of 1/4 FL)."""

EMERGENCY_CODES = {0o7500: "unlawful_interference", 0o7600: "no_communications",
                   0o7700: "general"}  # fmt: skip
"""The Mode-3/A emergency codes and the emergency each declares."""


class Emergency(StrEnum):
    """Emergency status (the codes of I062/380 EMC and ADS-B)."""

    GENERAL = "general"
    MEDICAL = "medical"
    MINIMUM_FUEL = "minimum_fuel"
    NO_COMMUNICATIONS = "no_communications"
    UNLAWFUL_INTERFERENCE = "unlawful_interference"
    DOWNED_AIRCRAFT = "downed_aircraft"


@dataclass(frozen=True)
class Quantity:
    """A downlinked parameter: column/field ``name``, bounds (``hi_open``: ``hi`` is
    excluded), ``unit`` and description (with its source register)."""

    name: str
    lo: float
    hi: float
    unit: str
    description: str
    hi_open: bool = False


DOWNLINKED: tuple[Quantity, ...] = (
    Quantity("selected_altitude_mcp", 0.0, 700.0, "FL",
             "MCP/FCU selected altitude (BDS 4,0), FL (pressure altitude / 100 ft)"),
    Quantity("selected_altitude_fms", 0.0, 700.0, "FL",
             "FMS selected altitude (BDS 4,0), FL (pressure altitude / 100 ft)"),
    Quantity("roll_angle", -math.pi / 2, math.pi / 2, "rad",
             "Roll angle (BDS 5,0), rad, positive right wing down"),
    Quantity("true_track", 0.0, 2 * math.pi, "rad",
             "True track angle (BDS 5,0), rad clockwise from true north", hi_open=True),
    Quantity("ground_speed", 0.0, 1100.0, "m/s", "Ground speed (BDS 5,0), m/s"),
    Quantity("track_angle_rate", -0.3, 0.3, "rad/s",
             "Track angle rate (BDS 5,0), rad/s, positive clockwise"),
    Quantity("true_airspeed", 0.0, 1100.0, "m/s", "True airspeed (BDS 5,0), m/s"),
    Quantity("magnetic_heading", 0.0, 2 * math.pi, "rad",
             "Magnetic heading (BDS 6,0), rad clockwise from magnetic north", hi_open=True),
    Quantity("indicated_airspeed", 0.0, 600.0, "m/s", "Indicated airspeed (BDS 6,0), m/s"),
    Quantity("mach", 0.0, 4.1, "", "Mach number (BDS 6,0)"),
    Quantity("baro_vertical_rate", -100.0, 100.0, "m/s",
             "Barometric altitude rate (BDS 6,0), m/s, positive up"),
    Quantity("inertial_vertical_rate", -100.0, 100.0, "m/s",
             "Inertial vertical velocity (BDS 6,0), m/s, positive up"),
)  # fmt: skip
"""The downlinked parameters (bounds: the registers' ranges, e.g. 2,046 kt, ±16 °/s,
±16,384 ft/min)."""
DOWNLINKED_BY_NAME = {q.name: q for q in DOWNLINKED}
DOWNLINK_REGISTERS = {
    "4,0": ("selected_altitude_mcp", "selected_altitude_fms"),
    "5,0": ("roll_angle", "true_track", "ground_speed", "track_angle_rate", "true_airspeed"),
    "6,0": ("magnetic_heading", "indicated_airspeed", "mach", "baro_vertical_rate",
            "inertial_vertical_rate"),
}  # fmt: skip
"""Which register carries which parameter."""


def emergency_of_code(code: int | None) -> Emergency | None:
    """The emergency a Mode-3/A code declares (7500, 7600, 7700), else ``None``."""
    name = EMERGENCY_CODES.get(code) if code is not None else None
    return None if name is None else Emergency(name)


def mode_3a_text(code: int | None) -> str:
    """A Mode-3/A code as its four octal digits (``"7700"``), ``""`` for none."""
    return "" if code is None or code < 0 else f"{code:04o}"
