"""Measures for recordings whose only truth is a label on each plot (e.g. the Mode-S address).

The [thesis] ch. 7 measures adapted to real data, where no true states exist. Input is
one row per plot: its time, its aircraft label (Mode-S 24-bit address, −1 if the plot has
none), the id of the track it updated (−1 if none) and whether that track was confirmed at
that time. Measures:

* **completeness**: share of labelled aircraft (distinct labels) with at least one plot
  that updated a confirmed track.
* **track-id changes per aircraft**: along an aircraft's plots in time order, restricted to
  plots that updated a confirmed track, the number of times the track id differs from the
  previous one (0 for an aircraft held by one track; duplicates that alternate count).
* **confirmed false tracks per hour**: a confirmed track (one that was updated with at
  least one plot while confirmed) is false when its most frequent aircraft label covers
  less than ``min_label_share`` (0.5) of its plots while confirmed (unlabelled plots count
  against it). Caveat: a track on an aircraft without Mode-S is counted false, so use this
  on Mode-S-only traffic or simulations. Rate = count / (duration in hours); the duration
  is the plot time span unless given.
* **time to confirm**: per aircraft, time of its first plot that updated a confirmed track
  minus the time of its first labelled plot (s); the mean is over aircraft that got one.
  Aircraft first seen within ``warmup_s`` of the first plot are excluded from this mean
  (they may have been in the radar coverage before the recording began).

Times in seconds (any epoch); labels and track ids non-negative integers, −1 for none.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NO_LABEL = -1
NO_TRACK = -1


@dataclass(frozen=True)
class LabelMetrics:
    """Results of ``label_metrics``.

    aircraft: (a,) labels, sorted. has_confirmed: (a,) bool. id_changes: (a,) int.
    time_to_confirm: (a,) s, NaN if the aircraft never had a confirmed track.
    completeness: share in [0, 1] (NaN when no labelled aircraft). mean_id_changes: mean of
    id_changes. confirmed_tracks: ids of confirmed tracks; false_tracks: those counted false.
    false_per_hour: len(false_tracks) per hour of ``duration_s``. mean_time_to_confirm: s,
    over aircraft that got one and were first seen after the warm-up (NaN if none).
    """

    aircraft: np.ndarray
    has_confirmed: np.ndarray
    id_changes: np.ndarray
    time_to_confirm: np.ndarray
    completeness: float
    mean_id_changes: float
    confirmed_tracks: np.ndarray
    false_tracks: np.ndarray
    duration_s: float
    false_per_hour: float
    mean_time_to_confirm: float


def _int_vector(name: str, a: np.ndarray, n: int) -> np.ndarray:
    a = np.asarray(a)
    if a.size == 0:
        a = a.astype(np.int64).reshape(0)
    if a.shape != (n,) or not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"{name}: shape {a.shape}, dtype {a.dtype}: must be ({n},) integers")
    if np.any(a < -1):
        raise ValueError(f"{name}: value {int(a.min())}: must be >= 0, or -1 for none")
    return a.astype(np.int64)


def _validated(plot_time, plot_label, plot_track, plot_track_confirmed, duration_s,
               min_label_share):  # fmt: skip
    """The inputs of :func:`label_metrics` as checked arrays, and the duration (s)."""
    t = np.asarray(plot_time, dtype=np.float64).reshape(-1)
    n = len(t)
    if not np.all(np.isfinite(t)):
        raise ValueError("plot_time: contains non-finite values: times must be finite")
    label = _int_vector("plot_label", plot_label, n)
    track = _int_vector("plot_track", plot_track, n)
    conf = np.asarray(plot_track_confirmed)
    if conf.shape != (n,) or conf.dtype != bool:
        raise ValueError(
            f"plot_track_confirmed: shape {conf.shape}, dtype {conf.dtype}: must be ({n},) bool"
        )
    if np.any(conf & (track == NO_TRACK)):
        raise ValueError("plot_track_confirmed: True on a plot with plot_track = -1")
    if not 0 < min_label_share <= 1:
        raise ValueError(f"min_label_share = {min_label_share}: must be in (0, 1]")
    span = float(t.max() - t.min()) if n else 0.0
    duration = span if duration_s is None else float(duration_s)
    if duration_s is not None and not duration > 0:
        raise ValueError(f"duration_s = {duration_s}: must be > 0 s")
    return t, label, track, conf, duration


def label_metrics(
    plot_time: np.ndarray,
    plot_label: np.ndarray,
    plot_track: np.ndarray,
    plot_track_confirmed: np.ndarray,
    duration_s: float | None = None,
    min_label_share: float = 0.5,
    warmup_s: float = 0.0,
) -> LabelMetrics:
    """Completeness, id changes, false tracks per hour and time to confirm (module docstring)."""
    t, label, track, conf, duration = _validated(
        plot_time, plot_label, plot_track, plot_track_confirmed, duration_s, min_label_share
    )
    n = len(t)

    order = np.argsort(t, kind="stable")
    t, label, track, conf = t[order], label[order], track[order], conf[order]

    # Per aircraft (plots sorted by time, then grouped by label with a stable sort).
    lab = label != NO_LABEL
    aircraft, first_idx = np.unique(label[lab], return_index=True)
    t_first = t[lab][first_idx]
    a = len(aircraft)
    has_confirmed = np.zeros(a, dtype=bool)
    id_changes = np.zeros(a, dtype=np.int64)
    ttc = np.full(a, np.nan)
    held = lab & conf
    if held.any():
        g = np.searchsorted(aircraft, label[held])
        th, trk = t[held], track[held]
        by = np.argsort(g, kind="stable")  # grouped by aircraft, time order kept
        g, th, trk = g[by], th[by], trk[by]
        starts = np.flatnonzero(np.r_[True, g[1:] != g[:-1]])
        has_confirmed[g[starts]] = True
        ttc[g[starts]] = th[starts] - t_first[g[starts]]
        change = np.r_[False, (g[1:] == g[:-1]) & (trk[1:] != trk[:-1])]
        id_changes = np.bincount(g[change], minlength=a).astype(np.int64)

    # Confirmed tracks and their dominant-label share while confirmed.
    ct = track[conf]
    cl = label[conf]
    confirmed_tracks, n_plots = np.unique(ct, return_counts=True)
    false_tracks = confirmed_tracks
    if len(ct):
        pairs = np.unique(np.column_stack([ct[cl >= 0], cl[cl >= 0]]), axis=0, return_counts=True)
        best = np.zeros(len(confirmed_tracks))
        if len(pairs[0]):
            ti = np.searchsorted(confirmed_tracks, pairs[0][:, 0])
            np.maximum.at(best, ti, pairs[1])
        false_tracks = confirmed_tracks[best / n_plots < min_label_share]

    later = t_first >= (t[0] + warmup_s if n else 0.0)
    use = has_confirmed & later
    return LabelMetrics(
        aircraft=aircraft,
        has_confirmed=has_confirmed,
        id_changes=id_changes,
        time_to_confirm=ttc,
        completeness=float(has_confirmed.mean()) if a else float("nan"),
        mean_id_changes=float(id_changes.mean()) if a else float("nan"),
        confirmed_tracks=confirmed_tracks,
        false_tracks=false_tracks,
        duration_s=duration,
        false_per_hour=len(false_tracks) / (duration / 3600.0) if duration > 0 else float("nan"),
        mean_time_to_confirm=float(ttc[use].mean()) if use.any() else float("nan"),
    )
