"""A sensor's own reports as tracks (``skyfuse eval --sensor-tracks FILE``): the baseline
"each sensor alone" of the reference scores, with no tracker of ours involved.

An airport multilateration system or surface movement radar (CAT010) tracks its targets
itself: every target report carries the sensor's track number (I161) and track status
(I170). :func:`read_sensor_tracks` turns the reports into
:class:`~skyfuse.fusion.metrics.reference_association.TrackUpdates`:

* one track id per (SAC, SIC, I161) *life*: a track number starts a new life after a
  report with I170 TRE = 1 (the sensor ended the track; the SMR sends such ends as
  reports without a position) or after ``new_track_gap_s`` (30 s) without a report —
  both sensors report every track every second, and reuse numbers;
* only reports of confirmed tracks (I170 CNF) with a position count, as only confirmed
  tracks of our tracker are published, and only measured ones: a coasted report (I170
  CST ≠ 0, the position extrapolated) is not an update, as a track of ours coasting
  without a plot is not; field monitors (I020 RAB = 1: the system's own
  fixed transponders) and simulated reports are left out; test targets are dropped by
  the decoder;
* the identity the sensor shows (Mode-S address I220, callsign I245, Mode-3/A I060) and
  the ground flag (:func:`~.surveillance_positions.ground_flags`: the SMR's reports are
  on the ground) go with each update.

Positions are placed in the evaluation frame by :mod:`.surveillance_positions` (I041,
else I042/I040 relative to the sensor's site from the sites file).
"""

from __future__ import annotations

import datetime as dt
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from skyfuse.fusion.metrics.reference_association import TrackUpdates
from skyfuse.services.asterix import cat010
from skyfuse.services.asterix.sites import radar_id_for
from skyfuse.services.evaluation.inputs import InputError, read_report_file
from skyfuse.services.evaluation.surveillance_positions import (
    ReportPositions,
    cat010_positions,
    ground_flags,
)

NEW_TRACK_GAP_S = 30.0


@dataclass
class SensorTracks:
    """The kept reports of a CAT010 file as track updates, positions as read, and the
    measured reports of tracks not (yet) confirmed (``confirmed`` False: not updates,
    but the sensor's input, for the input bound; :meth:`plots`)."""

    path: Path
    time_ns: np.ndarray
    track_id: np.ndarray
    mode_s: np.ndarray
    callsign: np.ndarray
    mode_3a: np.ndarray
    ground: np.ndarray
    positions: ReportPositions
    sensors: list[str] = field(default_factory=list)
    counts: Counter = field(default_factory=Counter)
    confirmed: np.ndarray | None = None

    def updates(self, frame, sites: dict) -> TrackUpdates:
        """The updates placed in ``frame``; rows whose sensor has no site in ``sites``
        are left out (``no_site``)."""
        x, y, ok = self.positions.in_frame(frame, sites)
        self.counts["no_site"] = int((~ok).sum())
        if self.confirmed is not None:
            ok &= self.confirmed
        return TrackUpdates(
            self.time_ns[ok], self.track_id[ok], x[ok], y[ok], self.mode_s[ok],
            self.callsign[ok], self.mode_3a[ok], self.ground[ok].astype(np.int8),
        )  # fmt: skip

    def plots(self, frame, sites: dict):
        """Every measured report, confirmed or not, as the input plots of the input bound
        (:class:`~skyfuse.fusion.metrics.reference_coverage.InputPlots`, with the
        Mode-S address the report shows)."""
        from skyfuse.fusion.metrics.reference_coverage import InputPlots

        x, y, ok = self.positions.in_frame(frame, sites)
        return InputPlots(self.time_ns[ok], x[ok], y[ok], mode_s=self.mode_s[ok])

    def summary(self) -> dict:
        conf = np.ones(len(self.time_ns), bool) if self.confirmed is None else self.confirmed
        return {
            "file": str(self.path),
            "sensors": self.sensors,
            "reports": int(conf.sum()),
            "tracks": len(np.unique(self.track_id[conf])),
            "counts": dict(self.counts),
        }


def track_lives(
    source: np.ndarray, number: np.ndarray, time_ns: np.ndarray, end: np.ndarray, gap_s: float
) -> np.ndarray:
    """(n,) track id of each report: one per life of a (source, track number) pair (module
    docstring), numbered in order of first appearance; reports in file order."""
    n = len(number)
    order = np.lexsort((np.arange(n), time_ns, number, source))
    src, num, t, e = source[order], number[order], time_ns[order], end[order]
    new_pair = np.r_[True, (src[1:] != src[:-1]) | (num[1:] != num[:-1])]
    after_end = np.r_[False, e[:-1]]
    late = np.r_[False, np.diff(t) > gap_s * 1e9]
    life = np.cumsum(new_pair | after_end | late) - 1
    out = np.empty(n, np.int64)
    out[order] = life
    first = np.full(life.max() + 1 if n else 0, n, np.int64)
    np.minimum.at(first, out, np.arange(n))
    return np.argsort(np.argsort(first, kind="stable"), kind="stable")[out]


def read_sensor_tracks(
    path: str | Path, *, date: dt.date | str | None = None, new_track_gap_s: float = NEW_TRACK_GAP_S
) -> SensorTracks:
    """The CAT010 reports of ``path`` as tracks (module docstring); InputError when the
    file is missing or holds no CAT010 target reports with track numbers."""
    path = Path(path)
    reports, stats = read_report_file(path, "sensor tracks file", date)
    reps = [r for r in reports if isinstance(r, cat010.Cat010Report) and r.track_number is not None]
    if not reps:
        read = ", ".join(f"{k} {v}" for k, v in stats.items()) or "nothing decoded"
        raise InputError(f"{path}: no CAT010 target reports with a track number ({read})")
    source = np.array([r.sac * 256 + r.sic for r in reps], np.int64)
    life = track_lives(
        source,
        np.array([r.track_number for r in reps], np.int64),
        np.array([r.time_ns for r in reps], np.int64),
        np.array([bool(r.last) for r in reps]),
        new_track_gap_s,
    )
    counts = Counter(
        {"reports": len(reps), **{k: v for k, v in stats.items() if k.endswith("test_target")}}
    )
    pos = cat010_positions(reps)
    keep = _kept(reps, pos, counts)
    measured = keep | _unconfirmed_measured(reps, pos)
    rows = np.flatnonzero(measured)
    kept = [reps[i] for i in rows]
    return SensorTracks(
        path=path,
        time_ns=np.array([r.time_ns for r in kept], np.int64),
        track_id=life[rows],
        mode_s=np.array([-1 if r.mode_s is None else r.mode_s for r in kept], np.int64),
        callsign=np.array([r.callsign for r in kept], object),
        mode_3a=np.array([-1 if r.mode_3a is None else r.mode_3a for r in kept], np.int64),
        ground=ground_flags(kept),
        positions=pos.take(rows),
        sensors=sorted({radar_id_for(r.sac, r.sic) for r, k in zip(kept, keep[rows]) if k}),
        counts=counts,
        confirmed=keep[rows],
    )


def _unconfirmed_measured(reps: list, pos: ReportPositions) -> np.ndarray:
    """Reports of tracks not confirmed, measured (not coasted), with a position, neither
    field monitors nor simulated: the sensor's input, not its updates."""
    ok = [r.confirmed is False and not (r.coasted or r.rab or r.sim) for r in reps]
    return pos.placeable & np.array(ok, bool)


def _kept(reps: list, pos: ReportPositions, counts: Counter) -> np.ndarray:
    """Reports that are confirmed track updates with a position (the others counted)."""
    keep = np.ones(len(reps), bool)
    placeable = pos.placeable
    for i, r in enumerate(reps):
        reason = (
            "field_monitor" if r.rab
            else "simulated" if r.sim
            else "no_position" if not placeable[i]
            else "not_confirmed" if r.confirmed is False
            else "coasted" if r.coasted
            else None
        )  # fmt: skip
        if reason is not None:
            counts[reason] += 1
            keep[i] = False
    return keep
