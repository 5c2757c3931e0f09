"""Airborne / surface split of the Mode-S label measures (docs/reports/registration-log.md §4-5).

Real airport-area recordings mix airborne aircraft with aircraft taxiing on the surface
(low speed, sharp turns, flight level ≈ 0, often near the radar), whose tracks fragment
for reasons of their own. Each plot is classed from its reported flight level and slant
range (the classes of that page's measurement):

* ``AIRBORNE`` — flight level ≥ ``min_flight_level`` (10) and slant range ≥
  ``min_range_nm`` (2 NM);
* ``SURFACE`` — flight level < ``min_flight_level``;
* ``OVERHEAD`` — airborne but within ``min_range_nm`` of the radar;
* ``UNKNOWN`` — no flight level.

:func:`split_label_metrics` computes, per class, over the plots of that class: aircraft,
completeness, track ids per aircraft (distinct confirmed track ids an aircraft's plots
updated), the share of aircraft on one track id, track-id changes per aircraft
(:func:`fusion.metrics.label_metrics.label_metrics`), confirmed tracks and confirmed
false tracks (a track's class is the class of most of its confirmed plots; falseness is
judged over all its plots, min_label_share 0.5 as in label_metrics). Pure arrays in,
plain dict out — for the offline evaluation runner to report.
"""

from __future__ import annotations

import numpy as np

from .label_metrics import NO_LABEL, label_metrics

FT = 0.3048
NM = 1852.0
AIRBORNE, SURFACE, OVERHEAD, UNKNOWN = 1, 0, 2, -1
CLASS_NAMES = {AIRBORNE: "airborne", SURFACE: "surface", OVERHEAD: "overhead"}


def traffic_class(
    altitude_m, slant_range_m, *, min_flight_level: float = 10.0, min_range_nm: float = 2.0
) -> np.ndarray:
    """(n,) int8 class of each plot from its altitude (m; FL × 30.48 m, NaN = none) and
    slant range (m)."""
    alt = np.asarray(altitude_m, float)
    rng = np.asarray(slant_range_m, float)
    out = np.full(alt.shape, UNKNOWN, np.int8)
    known = np.isfinite(alt)
    high = known & (alt >= min_flight_level * 100.0 * FT)
    out[known & ~high] = SURFACE
    out[high] = np.where(rng[high] >= min_range_nm * NM, AIRBORNE, OVERHEAD)
    return out


def _track_ids_per_aircraft(label, track, conf) -> np.ndarray:
    """Distinct confirmed track ids per labelled aircraft (aircraft with one or more)."""
    keep = (label != NO_LABEL) & conf
    pairs = np.unique(np.column_stack([label[keep], track[keep]]), axis=0)
    if not len(pairs):
        return np.zeros(0, np.int64)
    _, counts = np.unique(pairs[:, 0], return_counts=True)
    return counts


def _track_classes(track, conf, cls) -> tuple[np.ndarray, np.ndarray]:
    """(confirmed track ids, the class of most of each one's confirmed plots)."""
    ct, cc = track[conf], cls[conf]
    ids = np.unique(ct)
    votes = np.zeros((len(ids), 4), np.int64)  # columns: classes −1, 0, 1, 2
    np.add.at(votes, (np.searchsorted(ids, ct), cc.astype(np.int64) + 1), 1)
    return ids, np.argmax(votes, axis=1) - 1


def split_label_metrics(
    plot_time, plot_label, plot_track, plot_confirmed, plot_class, *, min_label_share=0.5
) -> dict:
    """Label measures per traffic class and for all plots (module docstring): a dict
    ``{"all": {...}, "airborne": {...}, "surface": {...}, "overhead": {...}}``."""
    t = np.asarray(plot_time, float)
    label = np.asarray(plot_label, np.int64)
    track = np.asarray(plot_track, np.int64)
    conf = np.asarray(plot_confirmed, bool)
    cls = np.asarray(plot_class, np.int8)
    full = label_metrics(t, label, track, conf, min_label_share=min_label_share)
    ids, track_cls = _track_classes(track, conf, cls)
    false = np.isin(ids, full.false_tracks)
    out = {}
    groups = [("all", None)] + [(n, c) for c, n in CLASS_NAMES.items()]
    for name, c in groups:
        sel = np.ones(len(t), bool) if c is None else cls == c
        lm = label_metrics(t[sel], label[sel], track[sel], conf[sel],
                           min_label_share=min_label_share)  # fmt: skip
        per = _track_ids_per_aircraft(label[sel], track[sel], conf[sel])
        mine = np.ones(len(ids), bool) if c is None else track_cls == c
        n_conf, n_false = int(mine.sum()), int((mine & false).sum())
        out[name] = {
            "plots": int(sel.sum()),
            "aircraft": len(lm.aircraft),
            "completeness": _num(lm.completeness),
            "track_ids_per_aircraft": _num(per.mean()) if len(per) else None,
            "one_track_share": _num((per == 1).mean()) if len(per) else None,
            "id_changes_per_aircraft": _num(lm.mean_id_changes),
            "confirmed_tracks": n_conf,
            "confirmed_false_tracks": n_false,
            "false_track_share": _num(n_false / n_conf) if n_conf else None,
        }
    return out


def _num(v) -> float | None:
    v = float(v)
    return round(v, 4) if np.isfinite(v) else None
