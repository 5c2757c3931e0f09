"""Secondary-surveillance identity of simulated aircraft and of their replies.

Per aircraft (:func:`assign_identities`, drawn from a stream of its own, so the
trajectories and the plots of a seed do not change): a Mode-3/A code and a Mode-S
address (the scenario's), a callsign for Mode-S aircraft (an airline designator and a
flight number), and optionally

* a **code change**: a share ``code_change_fraction`` of the aircraft with a code are
  given a new code at a uniform time in the run (``emergency_fraction`` of them change
  to 7700 instead);
* **enhanced surveillance**: a share ``ehs_fraction`` of the Mode-S aircraft downlink
  their track and turn report and vertical rate (BDS 5,0 and 6,0).

Per reply (:func:`reply_columns`, the plot columns of :mod:`schemas.identity`):

* ``mode_3a``: the aircraft's code at the plot time; ``flight_level``: its height as a
  flight level, ``z / 30.48 m`` (the simulator's atmosphere is ISA at 1013.25 hPa, so
  the pressure altitude is the height), quantised to 1/4 FL — for 2-D radars the same
  value as the ``altitude`` column (Mode C, noisy and quantised by the radar model);
* with probability ``garble_probability`` each, a reply's code or flight level is
  *garbled*: one random bit of the code flipped, or the level off by a random multiple
  of 100 ft (up to ±1,000 ft), and the G flag set (so a consumer can drop it; the plot
  of a 2-D radar then has no altitude, as the ASTERIX reader leaves it);
* downlinked parameters of EHS aircraft from the truth at the plot time: ground speed
  and true track (velocity east/north), track angle rate (the track's change over
  ±0.5 s), roll angle of a coordinated turn φ = atan(V ω / g), inertial and barometric
  vertical rate (equal in ISA), all rounded to their register's LSB when written to
  ASTERIX, not here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymap3d

G0 = 9.80665
"""Standard gravity, m/s²."""
FL_M = 30.48
"""One flight level (100 ft) in metres."""
EMERGENCY = 0o7700
AIRLINES = ("JAT", "ASL", "WZZ", "RYR", "DLH", "AFR", "THY", "LOT", "AUA", "ROT", "BAW",
            "EZY", "KLM", "SWR", "TAP", "CSA", "LZB", "QTR", "UAE", "FIN")  # fmt: skip
"""ICAO airline designators the simulated callsigns use."""


@dataclass(frozen=True)
class IdentityParams:
    """How identities change and replies fail (scenario parameters of the same names)."""

    code_change_fraction: float = 0.0
    emergency_fraction: float = 0.0
    ehs_fraction: float = 0.0
    garble_probability: float = 0.0


def identity_rng(seed: int) -> np.random.Generator:
    """The stream of the aircraft identities (independent of the trajectories')."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(2,)))


def make_callsigns(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` distinct callsigns (object array): designator + 1-4 digits (+ a letter)."""
    out: list[str] = []
    seen: set[str] = set()
    while len(out) < n:
        number = str(int(rng.integers(1, 10_000)))
        suffix = chr(ord("A") + int(rng.integers(26))) if rng.random() < 0.3 else ""
        text = AIRLINES[int(rng.integers(len(AIRLINES)))] + (number + suffix)[:5]
        if text not in seen:
            seen.add(text)
            out.append(text)
    return np.asarray(out, dtype=object)


def assign_identities(targets, rng: np.random.Generator, duration: float, p: IdentityParams):
    """Fill ``targets``' callsigns, code changes and EHS flags (see the module docstring)."""
    n = len(targets)
    has_s = targets.mode_s >= 0
    targets.callsign = np.where(has_s, make_callsigns(rng, n), "").astype(object)
    u_change, u_emerg, u_time, u_ehs = rng.random((4, n))
    new_code = rng.integers(0o1000, 0o7000, n)
    change = (targets.mode_3a >= 0) & (u_change < p.code_change_fraction)
    emergency = change & (u_emerg < p.emergency_fraction)
    new_code = np.where(new_code == targets.mode_3a, new_code ^ 1, new_code)
    targets.mode_3a_after = np.where(change, np.where(emergency, EMERGENCY, new_code), -1)
    targets.mode_3a_change_time = np.where(change, u_time * duration, np.inf)
    targets.ehs = has_s & (u_ehs < p.ehs_fraction)


def enu_kinematics(index: np.ndarray, t: np.ndarray, locate) -> dict[str, np.ndarray]:
    """Velocity east/north/up (m/s) and turn rate (rad/s, clockwise) at times ``t``
    from positions 0.5 s apart (pymap3d ENU offsets)."""
    lat, lon, alt = locate(index, t)
    out = {}
    tracks = []
    for dt in (-0.5, 0.5):
        la, lo, al = locate(index, t + dt)
        e, n, u = pymap3d.geodetic2enu(la, lo, al, lat, lon, alt)
        out[dt] = (np.asarray(e) / dt, np.asarray(n) / dt, np.asarray(u) / dt)
        tracks.append(np.arctan2(out[dt][0], out[dt][1]))
    ve = 0.5 * (out[-0.5][0] + out[0.5][0])
    vn = 0.5 * (out[-0.5][1] + out[0.5][1])
    vu = 0.5 * (out[-0.5][2] + out[0.5][2])
    turn = ((tracks[1] - tracks[0] + math.pi) % (2 * math.pi) - math.pi) / 0.5
    return {"ve": ve, "vn": vn, "vu": vu, "turn": turn}


def reply_columns(targets, index: np.ndarray, t: np.ndarray, height: np.ndarray, locate,
                  rng: np.random.Generator, garble: float) -> dict[str, np.ndarray]:  # fmt: skip
    """The secondary-surveillance columns (NaN / -1 / "" for none) of the target plots
    of aircraft ``index`` at times ``t`` (s after the start) with reported heights
    ``height`` (m: Mode C for 2-D radars, the true height for 3-D ones)."""
    m = index.size
    code = np.where(t >= targets.mode_3a_change_time[index], targets.mode_3a_after[index],
                    targets.mode_3a[index])  # fmt: skip
    has_code = code >= 0
    fl = np.where(has_code, np.round(height / FL_M * 4.0) / 4.0, np.nan)
    u = rng.random((2, m))
    bit = rng.integers(0, 12, m)
    step = rng.integers(1, 11, m) * np.where(rng.random(m) < 0.5, -1.0, 1.0)
    code_garbled = has_code & (u[0] < garble)
    fl_garbled = has_code & (u[1] < garble)
    code = np.where(code_garbled, code ^ (1 << bit), code)
    fl = np.clip(np.where(fl_garbled, fl + step, fl), -2048.0, 2048.0)
    cols = {
        "mode_3a": code,
        "mode_3a_garbled": code_garbled,
        "flight_level": fl,
        "flight_level_garbled": fl_garbled,
        "callsign": targets.callsign[index],
    }
    ehs = targets.ehs[index]
    nan = np.full(m, np.nan)
    for name in ("ground_speed", "true_track", "track_angle_rate", "roll_angle",
                 "inertial_vertical_rate", "baro_vertical_rate"):  # fmt: skip
        cols[name] = nan.copy()
    if ehs.any():
        k = enu_kinematics(index[ehs], t[ehs], locate)
        gs = np.hypot(k["ve"], k["vn"])
        rate = np.clip(k["turn"], -0.27, 0.27)
        cols["ground_speed"][ehs] = np.minimum(gs, 1050.0)
        track = np.arctan2(k["ve"], k["vn"]) % (2 * math.pi)
        cols["true_track"][ehs] = np.where(track >= 2 * math.pi, 0.0, track)
        cols["track_angle_rate"][ehs] = rate
        cols["roll_angle"][ehs] = np.arctan(gs * rate / G0)
        vz = np.clip(k["vu"], -83.0, 83.0)
        cols["inertial_vertical_rate"][ehs] = vz
        cols["baro_vertical_rate"][ehs] = vz
    return cols
