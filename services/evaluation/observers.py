"""Observers of the offline runner (:func:`skyfuse.services.evaluation.offline.run_offline`).

* :class:`Coverage` — the one "in coverage" rule: at time t a target is inside coverage
  when the plots read so far carry at least ``min_detections`` detections of it (its
  simulation ``target_id``), the last one at most ``window_s`` seconds before t. Targets
  no radar sees are not "missed".
* :class:`TruthObserver` — at every ``Truth`` message, the latest confirmed tracks,
  predicted with constant velocity to the truth time, against the targets in coverage,
  in the system plane (x east, y north, m): GOSPA (Rahmathullah, García-Fernández and
  Svensson, "Generalized optimal sub-pattern assignment metric", FUSION 2017: order p,
  cut-off c, α = 2, with the track-switch term of García-Fernández et al. 2020), the share
  of target samples with a confirmed track within c (truth coverage) and the RMSE of
  those tracks' positions, also split into truth samples in a turn and in straight flight
  (``position_rmse_by_phase``: turn rate from consecutive truth velocities,
  :mod:`skyfuse.fusion.metrics.turn_phase`).
* :class:`LabelObserver` — per-plot rows (time, label, track, confirmed) scored by
  :func:`skyfuse.fusion.metrics.label_metrics.label_metrics`: completeness, track-id
  changes per aircraft, confirmed false tracks per hour, time to confirm. The label is
  the plot's simulation ``target_id`` or, in real data, its Mode-S address (I048/220),
  and for plots without one their discrete Mode-3/A code (I048/070; :func:`mode_3a_fallback`);
  labels score tracks, they never drive association. With reported altitudes the same
  measures are given per traffic class (``labels_by_traffic``: airborne, surface,
  overhead, all; :mod:`skyfuse.fusion.metrics.traffic_split`). With a tracker that
  attributes identity, the identity the tracks showed (``identity``,
  :mod:`skyfuse.fusion.metrics.identity_metrics`): the share of confirmed-track updates
  whose track shows the plot's Mode-S address, the share of airborne aircraft whose track
  shows their callsign within two scans of confirmation, the flight-level agreement, and
  the identity conflicts (per hour, each listed with its time and the two identities).
* :class:`ReferenceObserver` — the confirmed tracks' updates (a plot updated them) scored
  against an independent reference (ADS-B or multilateration positions with addresses):
  probability of update, position error, continuity, duplicates, false tracks, correct
  identification, surface and airborne (:mod:`skyfuse.services.evaluation.reference_eval`,
  :mod:`skyfuse.fusion.metrics.reference_scores`).
* :class:`TrackWriter` — writes each step's TrackBatch and TrackEvents to MCAP on
  ``skyfuse/@v1/fusion/{id}/tracks`` and ``…/events``.
* :class:`Timing` — wall and CPU time up to the last step, ms per tracker step (mean,
  p95, max), plots/s (of the run, of the tracker steps alone).
"""

from __future__ import annotations

import time
from collections import Counter

import numpy as np
from skyfuse.schemas import PlotBatch, TrackBatch, TrackStatus, Truth, keys
from skyfuse.services.evaluation.numbers import json_number
from skyfuse.services.evaluation.offline import Observer, Step

NO_LABEL = -1
LABEL_WARMUP_S = 60.0
"""Default warm-up for real data: aircraft first seen this long after the first plot or
less are left out of the mean time to confirm (they may have been in coverage before)."""


class Coverage:
    """The "in coverage" rule (module docstring), over the plots' ``target_id``."""

    def __init__(self, window_s: float = 15.0, min_detections: int = 3) -> None:
        self.window_ns = int(window_s * 1e9)
        self.min_detections = min_detections
        self.count: Counter = Counter()
        self.last: dict[int, int] = {}
        self.first: dict[int, int] = {}

    def add(self, batch: PlotBatch) -> None:
        tid = batch.column("target_id")
        if tid is None or not len(tid):
            return
        t = batch.column("time")
        keep = tid >= 0
        ids, times = tid[keep], t[keep]
        for target in np.unique(ids).tolist():
            mine = times[ids == target]
            self.count[target] += len(mine)
            self.last[target] = max(self.last.get(target, 0), int(mine.max()))
            self.first.setdefault(target, int(mine.min()))

    def inside(self, t_ns: int, ids) -> np.ndarray:
        """(n,) bool: target ``ids[i]`` is in coverage at ``t_ns`` (plots read so far)."""
        return np.array(
            [
                self.count[i] >= self.min_detections
                and 0 <= t_ns - self.last.get(i, -(10**30)) <= self.window_ns
                for i in ids
            ],
            dtype=bool,
        )

    def detectable(self) -> set[int]:
        """Targets with at least ``min_detections`` detections in the whole run."""
        return {t for t, n in self.count.items() if n >= self.min_detections}


def _positions(x: np.ndarray, ix: tuple[int, int, int, int], dt) -> np.ndarray:
    """(n, 2) positions x + vx·dt, y + vy·dt from state columns ``ix`` = (x, vx, y, vy);
    ``dt`` (s) a scalar or one per row (tracks of a rebuilt picture have their own times)."""
    return np.column_stack([x[:, ix[0]] + x[:, ix[1]] * dt, x[:, ix[2]] + x[:, ix[3]] * dt])


class TruthObserver(Observer):
    """Truth GOSPA, truth coverage and position RMSE (module docstring)."""

    def __init__(
        self,
        coverage: Coverage | None = None,
        c: float = 500.0,
        p: float = 2.0,
        switch_penalty: float = 0.0,
    ) -> None:
        self.coverage = coverage or Coverage()
        self.c, self.p, self.switch_penalty = c, p, switch_penalty
        self.frame = None
        self.latest: tuple[int, np.ndarray, np.ndarray, tuple] | None = None
        self.samples: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        self.truth_ids: set[int] = set()
        self.has_truth = False
        self._last_vel: dict[int, tuple[int, float, float]] = {}
        self.turning: list[np.ndarray] = []

    def start(self, frame) -> None:
        self.frame = frame

    def on_plots(self, batch: PlotBatch) -> None:
        self.coverage.add(batch)

    def on_step(self, step: Step) -> None:
        out = step.out
        c = np.flatnonzero(out.confirmed)
        self.latest = (out.time_ns, out.ids[c].astype(np.int64), out.states[c], (0, 1, 2, 3))

    def on_tracks(self, tracks: TrackBatch) -> None:
        conf = [t for t in tracks.tracks if t.status == TrackStatus.CONFIRMED]
        lab = list(tracks.state_labels)
        ix = tuple(lab.index(n) for n in ("x", "vx", "y", "vy"))
        x = np.array([t.state for t in conf], dtype=float).reshape(len(conf), len(lab))
        ids = np.array([t.track_id for t in conf], dtype=np.int64)
        # a picture rebuilt from the delta feed holds each track at its own last time
        t_trk = np.array([t.time for t in conf], dtype=np.int64)
        self.latest = (t_trk, ids, x, ix)

    def on_truth(self, truth: Truth) -> None:
        self.has_truth = True
        self.truth_ids.update(truth.target_id)
        if self.latest is None or self.frame is None:
            return
        ids = np.asarray(truth.target_id, dtype=np.int64)
        keep = self.coverage.inside(truth.time, truth.target_id)
        if len(ids):
            x, y, _ = self.frame.from_geodetic(
                np.asarray(truth.lat), np.asarray(truth.lon), np.asarray(truth.alt)
            )
            pos = np.column_stack([x, y])[keep]
        else:
            pos = np.zeros((0, 2))
        t_trk, trk_ids, states, ix = self.latest
        est = _positions(states, ix, (truth.time - t_trk) * 1e-9)
        first = self.coverage.first
        settled = np.array(
            [truth.time - first.get(int(i), truth.time) > 2 * self.coverage.window_ns for i in ids],
            dtype=bool,
        )[keep]
        self.samples.append((ids[keep], pos, trk_ids, est, settled))
        self.turning.append(self._turn_flags(truth)[keep])

    def _turn_flags(self, truth: Truth) -> np.ndarray:
        """(n,) bool: each truth target turns at ≥ 0.5 °/s since its previous truth sample
        (:mod:`skyfuse.fusion.metrics.turn_phase`)."""
        from skyfuse.fusion.metrics.turn_phase import in_turn, turn_rate

        n = len(truth.target_id)
        if not n or len(truth.vel_east) != n:
            return np.zeros(n, dtype=bool)
        prev = [self._last_vel.get(int(i), (truth.time, 0.0, 0.0)) for i in truth.target_id]
        v_prev = np.array([p[1:] for p in prev], dtype=float).reshape(n, 2)
        dt = (truth.time - np.array([p[0] for p in prev], dtype=np.int64)) * 1e-9
        v = np.column_stack([truth.vel_east, truth.vel_north])
        for i, ve, vn in zip(truth.target_id, truth.vel_east, truth.vel_north):
            self._last_vel[int(i)] = (truth.time, float(ve), float(vn))
        return in_turn(turn_rate(v_prev, v, dt))

    def summary(self) -> dict:
        if not self.has_truth:
            return {}
        res = {"targets_truth": len(self.truth_ids)}
        res["targets_detectable"] = len(self.coverage.detectable())
        if not self.samples:
            return {"truth": {**res, "samples": 0}}
        return {"truth": {**res, **self._scores()}}

    def _scores(self) -> dict:
        from skyfuse.fusion.metrics.gospa import gospa_over_time

        t_ids, t_pos, e_ids, e_pos, settled = (list(a) for a in zip(*self.samples))
        g = gospa_over_time(
            t_ids, t_pos, e_ids, e_pos, c=self.c, p=self.p, switch_penalty=self.switch_penalty
        )
        from skyfuse.fusion.metrics.turn_phase import phase_rmse

        hit = [a >= 0 for a in g.assigned_track]
        sq, turn = [], []
        for k, h in enumerate(hit):
            if h.any():
                row = {int(i): j for j, i in enumerate(e_ids[k].tolist())}
                j = [row[int(i)] for i in g.assigned_track[k][h]]
                sq.append(((t_pos[k][h] - e_pos[k][j]) ** 2).sum(1))
                turn.append(self.turning[k][h])
        n = sum(len(h) for h in hit)
        n_settled = sum(int(s.sum()) for s in settled)
        confirmed = {int(i) for k, h in enumerate(hit) for i in t_ids[k][h].tolist()}
        half = g.distance[len(g.distance) // 2 :]
        return {
            "samples": len(t_ids),
            "target_samples_in_coverage": n,
            "coverage": json_number(sum(int(h.sum()) for h in hit) / n) if n else None,
            "coverage_after_acquisition": json_number(
                sum(int((h & s).sum()) for h, s in zip(hit, settled)) / n_settled
            )
            if n_settled
            else None,
            "position_rmse_m": json_number(np.sqrt(np.mean(np.concatenate(sq))), 1) if sq else None,
            "position_rmse_by_phase": phase_rmse(np.concatenate(sq), np.concatenate(turn))
            if sq
            else None,
            "targets_confirmed": len(confirmed & self.coverage.detectable()),
            "gospa": {
                "c_m": self.c,
                "p": self.p,
                "mean_m": json_number(np.mean(g.distance), 2),
                "mean_second_half_m": json_number(np.mean(half), 2) if len(half) else None,
                "final_m": json_number(g.distance[-1], 2),
                "final_missed": int(g.n_missed[-1]),
                "final_false": int(g.n_false[-1]),
                "mean_localisation": json_number(np.mean(g.localisation), 2),
                "mean_missed": json_number(np.mean(g.missed), 2),
                "mean_false": json_number(np.mean(g.false), 2),
                "missed_targets_mean": json_number(np.mean(g.n_missed), 3),
                "false_tracks_mean": json_number(np.mean(g.n_false), 3),
                "full_switches": int(g.full_switches.sum()),
                "half_switches": int(g.half_switches.sum()),
                "total_m": json_number(g.total, 2),
            },
        }


MODE_3A_LABEL_BASE = 1 << 24
"""Labels from a Mode-3/A code are ``MODE_3A_LABEL_BASE + code``: above every 24-bit
Mode-S address, so the two never collide."""

NON_DISCRETE_MODE_3A = (0o0000, 0o1200, 0o2000, 0o7000, 0o7500, 0o7600, 0o7700)
"""Mode-3/A codes shared by many aircraft (ICAO conspicuity / VFR 7000, 1200, 2000, the
emergency codes, 0000): they do not identify an aircraft and give no label."""


def mode_3a_fallback(mode_s: np.ndarray, mode_3a: np.ndarray | None) -> np.ndarray:
    """Scoring labels (n,): the Mode-S address where a plot has one, else its discrete
    Mode-3/A code as ``MODE_3A_LABEL_BASE + code`` (aircraft with Mode A/C only, e.g.
    light aircraft, are scored as aircraft instead of their tracks counting as false),
    else −1. Only ever used to score tracks, never to associate."""
    label = np.asarray(mode_s, np.int64).copy()
    if mode_3a is None:
        return label
    code = np.asarray(mode_3a, np.int64)
    use = (label < 0) & (code >= 0) & ~np.isin(code, NON_DISCRETE_MODE_3A)
    label[use] = MODE_3A_LABEL_BASE + code[use]
    return label


_IDENTITY = ("mode_s", "callsign", "flight_level", "scan_s", "track_mode_s",
             "track_callsign", "track_flight_level")  # fmt: skip
"""What :class:`PlotTrackRows` keeps per plot for the identity measures."""


class PlotTrackRows:
    """Per-plot rows (time s, label, track id, confirmed) collected batch by batch, and
    for a tracker that attributes identity the plot's Mode-S address, callsign (packed)
    and valid flight level with the credited track's after the step.

    ``add(batch, out)`` after each tracker step: ``batch`` the PlotBatch, ``out`` its
    :class:`~skyfuse.fusion.tracker.tracker.TrackerOutput` (whose ``batch.plot_ids`` map
    the tracker's valid plots back to the PlotBatch rows). Plots the conversion rejected
    keep track −1. When several tracks share the same most likely plot, the plot is
    credited to a confirmed one before a tentative one, then to the highest existence.
    ``label``: ``"target_id"``, ``"mode_s"`` or ``None`` (the first of the two a batch
    carries). Arrays over plots; no per-plot objects."""

    def __init__(self, label: str | None = None) -> None:
        self.label = label
        self.kind: str | None = label
        self._cols: list[list[np.ndarray]] = [[], [], [], []]
        self._geo: list[list[np.ndarray]] = [[], []]
        self._ident: list[list[np.ndarray]] = [[] for _ in _IDENTITY]

    def _labels(self, batch: PlotBatch) -> np.ndarray:
        for name in (self.label,) if self.label else ("target_id", "mode_s"):
            col = batch.column(name)
            if col is not None:
                self.kind = self.kind or name
                if name != "mode_s":
                    return col
                return mode_3a_fallback(col, batch.validated_column("mode_3a"))
        return np.full(len(batch), NO_LABEL, np.int64)

    def add(self, batch: PlotBatch, out, scan_s: float = float("nan")) -> None:
        """The plots of ``batch`` and the tracks of ``out`` they updated; ``scan_s``: the
        scan period of the batch's radar (identity measures)."""
        m = len(batch)
        if m == 0:
            return
        track = np.full(m, -1, np.int64)
        conf = np.zeros(m, bool)
        trow = np.full(m, -1, np.int64)  # the credited track's row of ``out``
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
            trow[plot[last]] = rows[last]
        if getattr(out, "identity", None) is not None:
            self._add_identity(batch, out.identity, trow, scan_s)
        for col, v in zip(
            self._cols, (batch.column("time") * 1e-9, self._labels(batch), track, conf)
        ):
            col.append(v)
        for col, name in zip(self._geo, ("altitude", "range")):
            v = batch.column(name)
            col.append(np.full(m, np.nan) if v is None else np.asarray(v, float))

    def _add_identity(self, batch: PlotBatch, ident, trow: np.ndarray, scan_s: float) -> None:
        """The identity rows of one batch (``ident``: the tracks' ``TrackIdentity``)."""
        from skyfuse.fusion.tracker.identity import CALLSIGN, MODE_S, pack_callsigns

        m, has = len(batch), trow >= 0
        none = np.full(m, -1, np.int64)
        mode_s, callsign = batch.column("mode_s"), batch.column("callsign")
        level = batch.validated_column("flight_level")
        shown = [none.copy(), none.copy(), np.full(m, np.nan)]
        for col, v in zip(shown, (ident.codes[:, MODE_S], ident.codes[:, CALLSIGN],
                                  ident.flight_level)):  # fmt: skip
            col[has] = v[trow[has]]
        nan = np.full(m, np.nan)
        values = (none if mode_s is None else mode_s,
                  none if callsign is None else pack_callsigns(callsign),
                  nan if level is None else level, np.full(m, scan_s), *shown)  # fmt: skip
        for col, v in zip(self._ident, values):
            col.append(v)

    def identity_rows(self):
        """The :class:`~skyfuse.fusion.metrics.identity_metrics.IdentityRows` of the
        plots so far (None when the tracker showed no identity)."""
        from skyfuse.fusion.metrics.identity_metrics import IdentityRows
        from skyfuse.fusion.metrics.traffic_split import traffic_class

        if not self._ident[0] or len(self._ident[0]) != len(self._cols[0]):
            return None
        t, _, track, conf = self.arrays()
        cols = dict(zip(_IDENTITY, (np.concatenate(c) for c in self._ident)))
        cls = traffic_class(*self.geometry())
        return IdentityRows(t=t, track=track, confirmed=conf, cls=cls, **cols)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(time s, label, track, confirmed), concatenated over the batches."""
        if not self._cols[0]:
            z = np.zeros(0, np.int64)
            return np.zeros(0), z, z.copy(), np.zeros(0, bool)
        t, label, track, conf = (np.concatenate(c) for c in self._cols)
        return t, label, track, conf

    def geometry(self) -> tuple[np.ndarray, np.ndarray]:
        """(reported altitude m, slant range m) of each row, NaN where the plot has none."""
        if not self._geo[0]:
            return np.zeros(0), np.zeros(0)
        return np.concatenate(self._geo[0]), np.concatenate(self._geo[1])

    def traffic_metrics(self, *, min_label_share: float = 0.5) -> dict | None:
        """The label measures per traffic class (airborne: FL ≥ 10 and ≥ 2 NM out;
        surface: FL < 10; overhead; all), :func:`fusion.metrics.traffic_split
        .split_label_metrics`; None when no plot reports an altitude."""
        from skyfuse.fusion.metrics.traffic_split import split_label_metrics, traffic_class

        alt, rng = self.geometry()
        if not np.isfinite(alt).any():
            return None
        t, label, track, conf = self.arrays()
        cls = traffic_class(alt, rng)
        return split_label_metrics(t, label, track, conf, cls, min_label_share=min_label_share)

    def metrics(self, *, warmup_s: float = 0.0, min_label_share: float = 0.5) -> dict:
        """The label metrics of the rows as a JSON-ready dict (see :func:`metrics_dict`)."""
        from skyfuse.fusion.metrics.label_metrics import label_metrics

        t, label, track, conf = self.arrays()
        lm = label_metrics(
            t, label, track, conf, warmup_s=warmup_s, min_label_share=min_label_share
        )
        return metrics_dict(lm, n_plots=len(t), n_labelled=int((label >= 0).sum()))


def metrics_dict(lm, *, n_plots: int, n_labelled: int) -> dict:
    """A :class:`~skyfuse.fusion.metrics.label_metrics.LabelMetrics` as JSON values."""
    ttc = lm.time_to_confirm[np.isfinite(lm.time_to_confirm)]
    return {
        "plots": n_plots,
        "plots_labelled": n_labelled,
        "aircraft": len(lm.aircraft),
        "aircraft_with_confirmed_track": int(lm.has_confirmed.sum()),
        "completeness": json_number(lm.completeness),
        "track_id_changes_per_aircraft": json_number(lm.mean_id_changes),
        "track_id_changes_total": int(lm.id_changes.sum()),
        "confirmed_tracks": len(lm.confirmed_tracks),
        "confirmed_false_tracks": len(lm.false_tracks),
        "confirmed_false_tracks_per_hour": json_number(lm.false_per_hour, 3),
        "false_track_ids": [int(i) for i in lm.false_tracks[:50]],
        "time_to_confirm_mean_s": json_number(lm.mean_time_to_confirm, 2),
        "time_to_confirm_median_s": json_number(np.median(ttc), 2) if len(ttc) else None,
        "duration_s": json_number(lm.duration_s, 2),
    }


class LabelObserver(Observer):
    """Label scoring of the plots (module docstring); summary key ``labels``."""

    def __init__(
        self, label: str | None = None, warmup_s: float = 0.0, min_label_share: float = 0.5
    ) -> None:
        self.rows = PlotTrackRows(label)
        self.warmup_s, self.min_label_share = warmup_s, min_label_share
        self.conflicts: list[tuple] = []

    def on_step(self, step: Step) -> None:
        self.rows.add(step.batch, step.out, float(getattr(step.site, "scan_period", np.nan)))
        for e in step.out.events:
            if e.kind == "identity_conflict":
                self.conflicts.append((e.time_ns * 1e-9, e.track_id, e.attribute, e.value,
                                       e.previous))  # fmt: skip

    def summary(self) -> dict:
        m = self.rows.metrics(warmup_s=self.warmup_s, min_label_share=self.min_label_share)
        out = {"labels": {"kind": self.rows.kind, **m}}
        split = self.rows.traffic_metrics(min_label_share=self.min_label_share)
        if split is not None:
            out["labels_by_traffic"] = split
        ident = self.rows.identity_rows()
        if ident is not None and (ident.mode_s >= 0).any():
            out["identity"] = identity_summary(ident, self.conflicts)
        return out


def identity_summary(rows, conflicts: list[tuple], limit: int = 200) -> dict:
    """The identity measures (:mod:`skyfuse.fusion.metrics.identity_metrics`) as JSON
    values; the conflicts and the aircraft whose callsign was late listed (at most
    ``limit`` each), times in s since the epoch and in UTC."""
    import datetime as dt

    from skyfuse.fusion.metrics import identity_metrics as im
    from skyfuse.fusion.tracker.identity import MODE_S, code_text

    def utc(t: float) -> str:
        return dt.datetime.fromtimestamp(t, dt.UTC).isoformat(timespec="milliseconds")

    n_s, ok_s = im.mode_s_correct(rows)
    n_fl, ok_fl = im.flight_level_agreement(rows)
    cs = im.callsign_shown(rows)
    incidents = im.conflict_incidents(conflicts)
    hours = im.duration_hours(rows.t)
    missed = [{"mode_s": code_text(MODE_S, a), "callsign": im.callsign_text(c),
               "confirmed_utc": utc(t)} for a, c, t in cs["missed"][:limit]]  # fmt: skip
    return {
        "mode_s_updates": n_s,
        "mode_s_correct": json_number(ok_s),
        "callsign_aircraft": cs["aircraft"],
        "callsign_within_2_scans": json_number(cs["share"]),
        "callsign_late": missed,
        "flight_level_updates": n_fl,
        "flight_level_within_1": json_number(ok_fl),
        "conflicts": len(incidents),
        "conflicts_per_hour": json_number(len(incidents) / hours, 3) if hours > 0 else None,
        "conflict_list": [{**c, "utc": utc(c["time_s"])} for c in incidents[:limit]],
    }


class ReferenceObserver(Observer):
    """Reference scoring of the run's tracks (module docstring); summary key
    ``reference``. ``reference``: a :class:`~skyfuse.services.evaluation.reference
    .ReferenceRecording`; ``sites``: radar id → RadarSite for references given relative
    to a site (CAT010 I042); ``config``: a ``ReferenceScoreConfig``; ``time_offset``:
    seconds added to the reference's times, or ``"auto"``; ``area``: the assessed area's
    polygons (:mod:`~skyfuse.services.evaluation.reference_area`). The plots the tracker
    was given are the input of the input bound."""

    def __init__(self, reference, sites=None, config=None, time_offset=0.0, area=()) -> None:
        from skyfuse.fusion.metrics.reference_scores import ReferenceScoreConfig
        from skyfuse.services.evaluation.reference_eval import PlotCollector, UpdateCollector

        self.reference = reference
        self.sites = dict(sites or {})
        self.config = config or ReferenceScoreConfig()
        self.time_offset = time_offset
        self.area = list(area)
        self.collector = UpdateCollector()
        self.plots = PlotCollector()
        self.steps = 0
        self.frame = None

    def start(self, frame) -> None:
        self.frame = frame

    def on_step(self, step: Step) -> None:
        self.collector.add_output(step.out)
        self.plots.add_output(step.out, step.batch)
        self.steps += 1

    def on_tracks(self, tracks: TrackBatch) -> None:
        self.collector.add_batch(tracks)

    def summary(self) -> dict:
        from skyfuse.services.evaluation.reference_area import area_in_frame, area_summary
        from skyfuse.services.evaluation.reference_eval import score_reference

        out = {"reference_file": self.reference.summary()}
        if self.frame is None:
            return {"reference": {**out, "note": "no tracks: nothing was scored"}}
        samples = self.reference.samples(self.frame, self.sites)
        scores = score_reference(
            self.collector.updates(), samples, self.config, self.time_offset,
            plots=self.plots.plots() if self.steps else None,
            area=area_in_frame(self.area, self.frame),
        )  # fmt: skip
        out["reference_file"] = self.reference.summary()  # with the no_site count
        return {"reference": {**out, **scores, "score_area": area_summary(self.area, self.config)}}


class TrackWriter(Observer):
    """Writes each step's TrackBatch and TrackEvents to ``writer``
    (a :class:`~skyfuse.services.recording.mcap_io.RecordingWriter`)."""

    def __init__(self, writer, fusion_id: str = "main") -> None:
        from skyfuse.schemas import TrackEvent
        from skyfuse.services.recording.mcap_io import SCHEMA_PREFIX, json_schema_bytes

        self.writer = writer
        self.events: Counter = Counter()
        # register the two channels once (their JSON Schemas are built once, not per write)
        self.tracks_ch, self.events_ch = (
            writer.channel_for(
                topic, schema_name=SCHEMA_PREFIX + model.__name__,
                schema_data=json_schema_bytes(model),
            )
            for topic, model in (
                (keys.fusion_tracks(fusion_id), TrackBatch),
                (keys.fusion_events(fusion_id), TrackEvent),
            )
        )  # fmt: skip

    def on_step(self, step: Step) -> None:
        tb, evs = step.wire()
        self.writer.write_raw(self.tracks_ch, tb.to_json_bytes(), step.batch.time_end)
        for e in evs:
            self.writer.write_raw(self.events_ch, e.to_json_bytes(), e.time)
            self.events[e.kind.value] += 1

    def summary(self) -> dict:
        return {"events": dict(self.events)}


class Timing(Observer):
    """Wall and CPU time of the run up to its last step (reading, conversion, tracking,
    the other observers' per-step work; not the summaries computed after the run, such
    as the truth scoring), ms per tracker step (mean, p95, max), plots/s over that time
    (``plots_per_s``) and over the tracker steps alone (``plots_per_s_steps``: the
    pipeline's conversion, tracker and output, as in the live service); summary key
    ``timing``."""

    def __init__(self) -> None:
        self.wall0, self.cpu0 = time.perf_counter(), time.process_time()
        self.wall1, self.cpu1 = self.wall0, self.cpu0
        self.ms: list[float] = []
        self.plots = 0

    def on_step(self, step: Step) -> None:
        self.ms.append(step.ms)
        self.plots += len(step.batch)
        self.wall1, self.cpu1 = time.perf_counter(), time.process_time()

    def summary(self) -> dict:
        wall = self.wall1 - self.wall0
        ms = np.asarray(self.ms) if self.ms else np.zeros(1)
        steps_s = float(np.sum(self.ms)) / 1e3
        return {
            "timing": {
                "wall_s": json_number(wall, 2),
                "cpu_s": json_number(self.cpu1 - self.cpu0, 2),
                "ms_per_batch_mean": json_number(ms.mean(), 3),
                "ms_per_batch_p95": json_number(np.percentile(ms, 95), 3),
                "ms_per_batch_max": json_number(ms.max(), 3),
                "plots_per_s": json_number(self.plots / wall, 1) if wall > 0 else None,
                "plots_per_s_steps": json_number(self.plots / steps_s, 1) if steps_s > 0 else None,
            }
        }
