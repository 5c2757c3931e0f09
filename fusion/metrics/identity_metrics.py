"""Identity correctness of the published tracks, for recordings whose plots carry a
Mode-S address (real data: I048/220; simulations: the aircraft's address).

Input: one row per plot that updated a track (the track it is credited to, as in
:mod:`.label_metrics`), with what the plot replied and what the track showed just after
the plot's step (the published values; :mod:`fusion.tracker.identity`). Measures:

* **Mode-S correct**: the share of confirmed-track updates by a plot with a Mode-S
  address whose track shows that address (a track showing none counts as wrong);
* **callsign within 2 scans**: the share of airborne aircraft that transmit a callsign
  whose track shows it within two scans of confirmation: an aircraft's confirmation is
  its first plot that updated a confirmed track (time t_c, the scan period T of that
  plot's radar); it counts when one of its confirmed-track updates up to
  t_c + (2 + ½) T (two scans, with half a scan for the aircraft's motion in azimuth)
  shows its callsign. Its callsign is the one its plots carry most often; an aircraft
  whose plots carry none by that time does not transmit one (left out); it is airborne
  when its confirming plot is (:mod:`.traffic_split`: FL ≥ 10, ≥ 2 NM);
* **flight-level agreement**: the share of confirmed-track updates by a plot with a
  valid flight level (validated, not garbled) whose track shows a level within
  ``fl_tolerance`` (1 FL) of it;
* **identity conflicts**: the tracker's ``identity_conflict`` events (a track that saw a
  second Mode-S address or callsign: a swap or a merge), counted per incident (one track
  at one time, whatever attributes), per hour of the plot time span, each listed.

Times in seconds; codes as integers (−1 none; callsigns packed as in
:func:`fusion.tracker.identity.pack_callsigns`); flight levels in FL (NaN none).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from skyfuse.fusion.tracker.identity import unpack_callsigns

from .traffic_split import AIRBORNE

NONE = -1
SCANS = 2.0
"""Scans after confirmation within which an aircraft's track should show its callsign."""
SCAN_SLACK = 0.5
"""Half a scan more: the aircraft's next plots come a little later as it moves in azimuth."""


@dataclass
class IdentityRows:
    """Per update: time ``t`` (s), ``track`` id, ``confirmed``, the plot's ``mode_s``,
    ``callsign``, valid ``flight_level``, its traffic class ``cls`` and its radar's
    scan period ``scan_s``; the track's ``track_mode_s``, ``track_callsign``,
    ``track_flight_level`` after the step (all (n,) arrays)."""

    t: np.ndarray
    track: np.ndarray
    confirmed: np.ndarray
    mode_s: np.ndarray
    callsign: np.ndarray
    flight_level: np.ndarray
    cls: np.ndarray
    scan_s: np.ndarray
    track_mode_s: np.ndarray
    track_callsign: np.ndarray
    track_flight_level: np.ndarray


def mode_s_correct(r: IdentityRows) -> tuple[int, float]:
    """(updates scored, share whose track shows the plot's Mode-S address)."""
    use = r.confirmed & (r.mode_s >= 0)
    n = int(use.sum())
    return n, float((r.track_mode_s[use] == r.mode_s[use]).mean()) if n else float("nan")


def flight_level_agreement(r: IdentityRows, tolerance: float = 1.0) -> tuple[int, float]:
    """(updates scored, share whose track's flight level is within ``tolerance`` FL)."""
    use = r.confirmed & np.isfinite(r.flight_level)
    n = int(use.sum())
    if not n:
        return 0, float("nan")
    diff = np.abs(r.track_flight_level[use] - r.flight_level[use])
    return n, float((diff <= tolerance).mean())  # NaN (no level shown) compares False


def _modal(values: np.ndarray) -> int:
    """The most frequent value (the smallest of equals)."""
    v, c = np.unique(values, return_counts=True)
    return int(v[np.argmax(c)])


def callsign_shown(r: IdentityRows) -> dict:
    """Per airborne aircraft (Mode-S address) that transmits a callsign: whether its
    track shows it within two scans of confirmation (module docstring). Returns counts,
    the share, and the aircraft that missed (address, callsign, time of confirmation)."""
    keep = np.flatnonzero(r.mode_s >= 0)
    rows = keep[np.lexsort((r.t[keep], r.mode_s[keep]))]  # by aircraft, then time
    starts = np.flatnonzero(np.r_[True, np.diff(r.mode_s[rows]) != 0])
    shown, missed = 0, []
    for i in np.split(rows, starts[1:]) if len(rows) else []:
        conf = i[r.confirmed[i]]
        if not len(conf) or r.cls[conf[0]] != AIRBORNE:
            continue
        first = conf[0]
        deadline = r.t[first] + (SCANS + SCAN_SLACK) * r.scan_s[first]
        if not ((r.t[i] <= deadline) & (r.callsign[i] >= 0)).any():
            continue  # no callsign transmitted by then
        callsign = _modal(r.callsign[i][r.callsign[i] >= 0])
        window = conf[r.t[conf] <= deadline]
        if (r.track_callsign[window] == callsign).any():
            shown += 1
        else:
            missed.append((int(r.mode_s[first]), callsign, float(r.t[first])))
    n = shown + len(missed)
    return {"aircraft": n, "shown": shown, "share": shown / n if n else float("nan"),
            "missed": missed}  # fmt: skip


def conflict_incidents(conflicts: list[tuple]) -> list[dict]:
    """The ``identity_conflict`` events ``(t s, track id, attribute, value, previous)``
    grouped per incident (track, time): each with its attributes' two identities."""
    out: dict[tuple[int, float], dict] = {}
    for t, track, attribute, value, previous in conflicts:
        inc = out.setdefault((int(track), float(t)), {"time_s": float(t), "track_id": int(track)})
        inc[attribute] = [previous, value]
    return sorted(out.values(), key=lambda d: (d["time_s"], d["track_id"]))


def callsign_text(packed: int) -> str:
    """A packed callsign as text."""
    return str(unpack_callsigns(np.array([packed]))[0]) if packed >= 0 else ""


def duration_hours(t: np.ndarray) -> float:
    """The plot time span in hours (NaN for fewer than two times)."""
    return float(t.max() - t.min()) / 3600.0 if len(t) > 1 else float("nan")
