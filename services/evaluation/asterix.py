"""Evaluation of a tracker on a real ASTERIX recording, with Mode-S addresses as labels.

Real recordings have no truth states; the aircraft identity carried by most plots — the
Mode-S address of I048/220 — is the label (issue 7 §5, issue 6 §1). The recording is
decoded (:func:`services.asterix.read_asterix`), tracked through the same
:class:`fusion.tracker.pipeline.TrackPipeline` as ``skyfuse track`` and the fusion
service (the tracker never sees the Mode-S address), and each plot is recorded with its
time, its label (−1 without Mode-S), the track it updated and whether that track was
confirmed after the update. :func:`fusion.metrics.label_metrics.label_metrics` turns
these rows into completeness, track-id changes per aircraft, confirmed false tracks per
hour and time to confirm.

"The track a plot updated" is the tracker's per-track most likely plot of the batch
(``TrackerOutput.assigned_plot``); when several tracks share the same most likely plot,
the plot is credited to a confirmed one before a tentative one, then to the highest
existence probability.
"""

from __future__ import annotations

import datetime as dt
import re
import time
from collections import Counter
from pathlib import Path

import numpy as np
from skyfuse.schemas import PlotBatch, RadarSite

NO_LABEL = -1
LABEL_WARMUP_S = 60.0
"""Default warm-up: aircraft first seen this long after the first plot or less are left
out of the mean time to confirm."""
_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def rejection_reasons(rejected: dict[str, int]) -> dict[str, int]:
    """Plot rejection counts with the numbers of each reason replaced by ``#`` (one key
    per kind of reason, not per value)."""
    out: Counter = Counter()
    for reason, n in rejected.items():
        out[_NUMBER.sub("#", reason)] += n
    return dict(out)


class PlotTrackRows:
    """Per-plot rows (time s, label, track id, confirmed) collected batch by batch.

    ``add(batch, out)`` after each tracker step: ``batch`` the PlotBatch, ``out`` its
    :class:`fusion.tracker.tracker.TrackerOutput` (whose ``batch.plot_ids`` map the
    tracker's valid plots back to the PlotBatch rows). Plots the conversion rejected
    keep track −1. Arrays over plots; no per-plot objects."""

    def __init__(self) -> None:
        self._t: list[np.ndarray] = []
        self._label: list[np.ndarray] = []
        self._track: list[np.ndarray] = []
        self._conf: list[np.ndarray] = []

    def add(self, batch: PlotBatch, out) -> None:
        m = len(batch)
        if m == 0:
            return
        label = batch.column("mode_s")
        label = np.full(m, NO_LABEL, np.int64) if label is None else label
        track = np.full(m, -1, np.int64)
        conf = np.zeros(m, bool)
        rows = np.flatnonzero(out.assigned_plot >= 0)
        if len(rows) and out.batch is not None and out.batch.plot_ids is not None:
            plot = np.asarray(out.batch.plot_ids)[out.assigned_plot[rows]]
            c = out.confirmed[rows].astype(bool)
            # sort so that for each plot the preferred track comes last
            order = np.lexsort((out.existence[rows], c, plot))
            plot, rows, c = plot[order], rows[order], c[order]
            last = np.r_[plot[1:] != plot[:-1], True]
            track[plot[last]] = out.ids[rows[last]]
            conf[plot[last]] = c[last]
        self._t.append(batch.column("time") * 1e-9)
        self._label.append(label)
        self._track.append(track)
        self._conf.append(conf)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(time s, label, track, confirmed), concatenated over the batches."""
        if not self._t:
            z = np.zeros(0, np.int64)
            return np.zeros(0), z, z.copy(), np.zeros(0, bool)
        return (
            np.concatenate(self._t),
            np.concatenate(self._label),
            np.concatenate(self._track),
            np.concatenate(self._conf),
        )

    def metrics(self, *, warmup_s: float = 0.0, min_label_share: float = 0.5) -> dict:
        """The label metrics of the rows as a JSON-ready dict (see :func:`metrics_dict`)."""
        from skyfuse.fusion.metrics.label_metrics import label_metrics

        t, label, track, conf = self.arrays()
        lm = label_metrics(
            t, label, track, conf, warmup_s=warmup_s, min_label_share=min_label_share
        )
        return metrics_dict(lm, n_plots=len(t), n_labelled=int((label >= 0).sum()))


def _num(v: float, nd: int = 4) -> float | None:
    return None if not np.isfinite(v) else round(float(v), nd)


def metrics_dict(lm, *, n_plots: int, n_labelled: int) -> dict:
    """A :class:`~fusion.metrics.label_metrics.LabelMetrics` as plain JSON values."""
    ttc = lm.time_to_confirm[np.isfinite(lm.time_to_confirm)]
    return {
        "plots": n_plots,
        "plots_with_mode_s": n_labelled,
        "aircraft": len(lm.aircraft),
        "aircraft_with_confirmed_track": int(lm.has_confirmed.sum()),
        "completeness": _num(lm.completeness),
        "track_id_changes_per_aircraft": _num(lm.mean_id_changes),
        "track_id_changes_total": int(lm.id_changes.sum()),
        "confirmed_tracks": len(lm.confirmed_tracks),
        "confirmed_false_tracks": len(lm.false_tracks),
        "confirmed_false_tracks_per_hour": _num(lm.false_per_hour, 3),
        "false_track_ids": [int(i) for i in lm.false_tracks[:50]],
        "time_to_confirm_mean_s": _num(lm.mean_time_to_confirm, 2),
        "time_to_confirm_median_s": _num(float(np.median(ttc)), 2) if len(ttc) else None,
        "duration_s": _num(lm.duration_s, 2),
    }


def evaluate_asterix(
    path: str | Path,
    *,
    sites: str | Path | dict[str, RadarSite] | None = None,
    date: dt.date | str | None = None,
    tracker_cfg=None,
    frame: str = "stereographic",
    sector_count: int = 16,
    assumed_altitude: float | None = 3000.0,
    warmup_s: float = LABEL_WARMUP_S,
    min_label_share: float = 0.5,
) -> dict:
    """Track an ASTERIX recording and report the Mode-S label metrics.

    ``path``: pcap or raw ``.ast`` file of CAT048/CAT034. ``sites``: a sites TOML path or
    ``{radar id: RadarSite}`` (radars without a site — none in the file's CAT034 I120
    either — are counted and skipped). ``date``: UTC date of the first record
    (``datetime.date`` or ``"YYYY-MM-DD"``; default: pcap capture time, else today).
    ``tracker_cfg``: a :class:`fusion.tracker.TrackerConfig` (default: its defaults).
    ``frame``: ``stereographic`` or ``ned`` system frame at the mean of the sites.
    ``assumed_altitude``: height (m, ± 3000 m) for plots without a flight level
    (primary-only), ``None`` to reject them. ``warmup_s``: aircraft first seen within
    this time of the first plot are left out of the mean time to confirm (they may have
    been in coverage before the recording). ``min_label_share``: see label_metrics.

    Returns a dict: ``metrics`` (completeness, track_id_changes_per_aircraft,
    confirmed_false_tracks_per_hour, time_to_confirm_mean_s, …), ``radars`` (plots per
    radar), ``sites`` used, ``batches``, ``plots_processed``, ``plots_rejected``,
    ``asterix`` (reader counts), ``tracker``, ``timing``. Raises ``ValueError`` for an
    unusable input (no radar with a site, unreadable sites file)."""
    from skyfuse.fusion.frames import SystemFrame
    from skyfuse.fusion.tracker import TrackerConfig
    from skyfuse.services.asterix import load_sites, read_asterix
    from skyfuse.services.fusion.pipeline import TrackPipeline

    if isinstance(date, str):
        try:
            date = dt.date.fromisoformat(date)
        except ValueError:
            raise ValueError(f"date {date!r} is not YYYY-MM-DD") from None
    if sites is not None and not isinstance(sites, dict):
        sites = load_sites(sites)
    tcfg = tracker_cfg if tracker_cfg is not None else TrackerConfig()
    t_start = time.perf_counter()
    res = read_asterix(path, date=date, sites=sites, sector_count=sector_count)
    t_read = time.perf_counter() - t_start
    if not res.sites:
        raise ValueError(
            f"{path}: no radar has a site (radars {', '.join(res.radars) or 'none'}): give a "
            "sites file with their positions"
        )
    lat0 = float(np.mean([s.lat for s in res.sites.values()]))
    lon0 = float(np.mean([s.lon for s in res.sites.values()]))
    sysframe = SystemFrame(frame, lat0, lon0, 0.0)
    pipe = TrackPipeline(sysframe, tcfg, assumed_altitude=assumed_altitude)
    rows = PlotTrackRows()
    counts: Counter = Counter()
    for batch in res.batches:
        site = res.sites.get(batch.radar_id)
        if site is None:
            counts["batches without a site"] += 1
            continue
        try:
            out = pipe.step(site, batch)
        except ValueError as e:
            counts[f"batches rejected: {e}"] += 1
            continue
        counts["batches"] += 1
        counts["plots"] += len(batch)
        rows.add(batch, out)
    metrics = rows.metrics(warmup_s=warmup_s, min_label_share=min_label_share)
    wall = time.perf_counter() - t_start
    return {
        "file": str(path),
        "tracker": tcfg.tracker,
        "depth": tcfg.memory_depth,
        "metrics": metrics,
        "radars": res.radars,
        "sites": {rid: res.scan_period_source.get(rid) for rid in sorted(res.sites)},
        "batches": counts["batches"],
        "plots_processed": counts["plots"],
        "plots_rejected": rejection_reasons(pipe.rejected),
        "counts": dict(counts),
        "asterix": res.stats,
        "tracker_config": tcfg.model_dump(mode="json"),
        "timing": {"read_s": round(t_read, 2), "wall_s": round(wall, 2)},
    }
