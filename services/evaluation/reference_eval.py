"""``skyfuse eval ... --reference REF``: tracks scored against an independent reference
(ADS-B or multilateration), by :func:`~skyfuse.fusion.metrics.reference_scores
.score_against_reference`.

Three sources of tracks, one scoring:

* ``skyfuse eval FILE --reference REF`` — the tracks our tracker makes of FILE in the
  offline runner (:class:`~skyfuse.services.evaluation.observers.ReferenceObserver`
  next to the other observers of :func:`~skyfuse.services.evaluation.recording
  .evaluate_recording`);
* ``skyfuse eval --tracks T.mcap --reference REF`` — the TrackBatch messages of a
  recording (``skyfuse track --out``, ``skyfuse record``), through the same runner with
  ``tracker=None``;
* ``skyfuse eval --sensor-tracks S.ast --reference REF`` — a CAT010 sensor's own tracks
  (:mod:`.sensor_tracks`): the "each sensor alone" baseline.

An update is a confirmed track's row whose plot count (``updates``) grew since the
track was last seen — a plot updated it — at that row's time, in the frame of the run.
``--reference-time-offset`` moves the reference's time stamps (s; ``auto``: by minus
the median along-track lead of the tracks over the reference, measured on updates
moving faster than ``min_offset_speed``, then scored again; both results are
reported). With the tracker's input (the plots of its steps; for ``--sensor-tracks`` the
file's measured reports) each phase also has the input-bound PoU and the PoU where the
input reported; with ``--score-area`` / ``--min-surface-speed`` the same phases inside
the assessed area, beside the whole (:mod:`~skyfuse.fusion.metrics.reference_coverage`,
:mod:`.reference_area`). Output: the JSON summary under ``reference`` and a table.
"""

from __future__ import annotations

import logging
from dataclasses import asdict
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, Field
from skyfuse.fusion.metrics.reference_association import TrackUpdates
from skyfuse.fusion.metrics.reference_coverage import InputPlots
from skyfuse.fusion.metrics.reference_scores import (
    PHASES,
    AreaScores,
    PhaseScores,
    ReferenceScoreConfig,
    ReferenceScores,
    WindowCounts,
    along_track_lead,
    score_against_reference,
)
from skyfuse.schemas import TrackBatch, TrackStatus
from skyfuse.services.evaluation.numbers import json_number

log = logging.getLogger(__name__)
MIN_LEAD_SAMPLES = 20


class ReferenceEvalOptions(BaseModel):
    """The reference and the tracks to score (``skyfuse eval`` flags)."""

    reference: Path | None = Field(
        None, description="ADS-B (CAT021) or multilateration (CAT010) recording to score against"
    )
    reference_date: str | None = Field(
        None, description="UTC date of the reference's first record, YYYY-MM-DD (default: --date)"
    )
    reference_kind: Literal["auto", "adsb", "mlat"] = Field(
        "auto", description="Reports the reference is made of (auto: ADS-B if any, else MLAT)"
    )
    reference_time_offset: float | Literal["auto"] = Field(
        0.0, description="Seconds added to the reference's times, or auto (estimated)"
    )
    reference_sigma_m: float | None = Field(
        None,
        gt=0,
        description="σ per axis of every reference report, m (default: ADS-B NACp/NUCp, "
        "MLAT I500, else 5 m)",
    )
    tracks: Path | None = Field(
        None, description="Score the TrackBatch messages of this MCAP instead of tracking"
    )
    sensor_tracks: Path | None = Field(
        None, description="Score this CAT010 file's own tracks (I161) instead of tracking"
    )
    score_area: list[str] = Field(
        default_factory=list,
        description="Assessed area, scored beside the whole: a TOML file of [[area]] polygons "
        "(vertices = [[lat, lon], ...]) or one polygon 'LAT LON; LAT LON; LAT LON'",
    )


class UpdateCollector:
    """Track updates gathered step by step (module docstring: an update is a confirmed
    row whose plot count grew), as arrays."""

    def __init__(self) -> None:
        self.known_ids = np.zeros(0, np.int64)
        self.known_updates = np.zeros(0, np.int64)
        self.parts: list[TrackUpdates] = []

    def _grew(self, ids: np.ndarray, updates: np.ndarray) -> np.ndarray:
        """(n,) bool: the plot count of each id grew since last seen; remembers them."""
        pos = np.searchsorted(self.known_ids, ids)
        found = pos < len(self.known_ids)
        found[found] = self.known_ids[pos[found]] == ids[found]
        prev = np.zeros(len(ids), np.int64)
        prev[found] = self.known_updates[pos[found]]
        self.known_updates[pos[found]] = updates[found]
        if (~found).any():
            ids_all = np.r_[self.known_ids, ids[~found]]
            upd_all = np.r_[self.known_updates, updates[~found]]
            order = np.argsort(ids_all, kind="stable")
            self.known_ids, self.known_updates = ids_all[order], upd_all[order]
        return updates > prev

    def add_output(self, out) -> None:
        """A tracker output (``TrackerOutput``: ids, confirmed, updates, states)."""
        ids = np.asarray(out.ids, np.int64)
        rows = np.flatnonzero(self._grew(ids, np.asarray(out.updates, np.int64)) & out.confirmed)
        if len(rows):
            x = out.predicted(rows)[0]
            t = np.full(len(rows), out.time_ns, np.int64)
            self.parts.append(TrackUpdates(t, ids[rows], x[:, 0], x[:, 2]))

    def add_batch(self, tb: TrackBatch) -> None:
        """A track picture (TrackBatch); the identity a track shows when it has one."""
        tracks = [t for t in tb.tracks]
        if not tracks:
            return
        ids = np.array([t.track_id for t in tracks], np.int64)
        upd = np.array([t.updates for t in tracks], np.int64)
        conf = np.array([t.status == TrackStatus.CONFIRMED for t in tracks])
        rows = np.flatnonzero(self._grew(ids, upd) & conf)
        if not len(rows):
            return
        lab = list(tb.state_labels)
        ix, iy = lab.index("x"), lab.index("y")
        sel = [tracks[i] for i in rows]
        ms = [getattr(t, "mode_s", None) for t in sel]
        m3 = [getattr(t, "mode_3a", None) for t in sel]
        self.parts.append(
            TrackUpdates(
                np.array([t.time for t in sel], np.int64), ids[rows],
                np.array([t.state[ix] for t in sel]), np.array([t.state[iy] for t in sel]),
                mode_s=np.array([-1 if v is None else v for v in ms], np.int64),
                callsign=np.array([getattr(t, "callsign", None) for t in sel], object),
                mode_3a=np.array([-1 if v is None else v for v in m3], np.int64),
            )
        )  # fmt: skip

    def updates(self) -> TrackUpdates:
        return TrackUpdates.concat(self.parts)


class PlotCollector:
    """The plots the tracker was given (its validated measurement batches: positions in
    the frame, each plot's time, the batch time, the Mode-S address when the plots show
    one), as :class:`~skyfuse.fusion.metrics.reference_coverage.InputPlots`."""

    def __init__(self) -> None:
        self.parts: list[InputPlots] = []

    def add_output(self, out, batch) -> None:
        """A tracker output (its ``batch``: the MeasurementBatch applied) of PlotBatch
        ``batch``."""
        mb = out.batch
        if mb is None or not len(mb.z):
            return
        n = len(mb.z)
        t = mb.plot_times if mb.plot_times is not None else np.full(n, mb.time_ns)
        ms = batch.column("mode_s")
        ids = mb.plot_ids
        mode_s = None if ms is None or ids is None else ms[ids]
        self.parts.append(InputPlots(np.asarray(t, np.int64), mb.z[:, 0], mb.z[:, 1],
                                     np.full(n, out.time_ns, np.int64), mode_s))  # fmt: skip

    def plots(self) -> InputPlots:
        return InputPlots.concat(self.parts)


def _num(v, digits: int = 4):
    return json_number(v, digits)


def counts_dict(c: WindowCounts | None) -> dict:
    """Windows of a phase with the input's: ``input_bound_pou``, ``pou_where_input``
    (None without the input)."""
    if c is None:
        return {}
    return {
        "input_windows": c.input,
        "input_bound_pou": None if c.input is None else _num(c.input_bound),
        "pou_where_input": None if c.input is None else _num(c.where_input),
        "windows_updated_without_input": c.updated_without_input,
    }


def _position_dict(p) -> dict:
    return {k: (_num(v, 3) if isinstance(v, float) else v) for k, v in asdict(p).items()}


def area_dict(a: AreaScores | None) -> dict | None:
    """A phase in the assessed area as JSON values (None without one)."""
    if a is None:
        return None
    return {
        "aircraft": a.aircraft,
        "windows": a.counts.windows,
        "windows_updated": a.counts.updated,
        "probability_of_update": _num(a.counts.probability_of_update),
        **counts_dict(a.counts),
        "position": _position_dict(a.position),
    }


def phase_dict(p: PhaseScores) -> dict:
    """One phase's scores as JSON values."""
    pos = _position_dict(p.position)
    ident = {
        name: {"checked": s.checked, "correct": s.correct, "share": _num(s.share)}
        for name, s in (("mode_s", p.mode_s), ("callsign", p.callsign), ("mode_3a", p.mode_3a))
    }
    return {
        "aircraft": p.aircraft,
        "windows": p.windows,
        "windows_updated": p.windows_updated,
        "probability_of_update": _num(p.probability_of_update),
        **counts_dict(p.coverage),
        "position": pos,
        "aircraft_tracked": p.aircraft_tracked,
        "track_ids_per_aircraft": _num(p.track_ids_per_aircraft),
        "aircraft_on_one_id": _num(p.aircraft_on_one_id),
        "id_changes": p.id_changes,
        "id_changes_per_aircraft": _num(p.id_changes_per_aircraft),
        "duplicate_windows": p.duplicate_windows,
        "duplicate_window_share": _num(p.duplicate_window_share),
        "duplicate_tracks": p.duplicate_tracks,
        "false_tracks": p.false_tracks,
        "false_track_ids": list(p.false_track_ids[:50]),
        "longest_false_s": _num(p.longest_false_s, 1),
        "outside_reference_tracks": p.outside_reference_tracks,
        "unassociated_near": p.unassociated_near,
        "identity": ident,
        "area": area_dict(p.area),
    }


def scores_dict(s: ReferenceScores) -> dict:
    """The whole result as JSON values (phases ``surface``, ``airborne``, ``all``)."""
    return {
        "reference_aircraft": len(s.aircraft_keys),
        "reference_aircraft_left_out": s.dropped_aircraft,
        "updates": s.updates,
        "updates_credited": s.credited,
        "tracks": s.tracks,
        "duration_s": _num(s.duration_s, 1),
        "time_offset_s": _num(s.time_offset_s, 3),
        **{p: phase_dict(getattr(s, p)) for p in PHASES},
        "per_aircraft": aircraft_rows(s),
    }


def aircraft_rows(s: ReferenceScores) -> list[dict]:
    """One row per reference aircraft with a window or a credited update."""
    a = s.per_aircraft
    rows = []
    for i, key in enumerate(a.key.tolist()):
        w = (int(a.windows_surface[i]), int(a.windows_airborne[i]))
        if not (sum(w) or a.tracks[i]):
            continue
        rows.append({
            "address": f"{key:06X}",
            "surface_windows": w[0], "surface_updated": int(a.updated_surface[i]),
            "airborne_windows": w[1], "airborne_updated": int(a.updated_airborne[i]),
            "tracks": int(a.tracks[i]), "id_changes": int(a.id_changes[i]),
            "rms_m": _num(a.rms_m[i], 2),
        })  # fmt: skip
        if a.input_surface is not None:
            rows[-1].update({
                "surface_input": int(a.input_surface[i]),
                "surface_input_updated": int(a.input_updated_surface[i]),
                "airborne_input": int(a.input_airborne[i]),
                "airborne_input_updated": int(a.input_updated_airborne[i]),
            })  # fmt: skip
    return rows


def score_reference(
    updates: TrackUpdates, samples, cfg: ReferenceScoreConfig, offset, *, plots=None, area=()
) -> dict:
    """Score with the given offset (s), or ``"auto"``: estimate it first (module
    docstring). The summary dict, with ``time_offset`` telling what was applied.
    ``plots``: the tracker's input (InputPlots) for the input bound; ``area``: the
    assessed area's polygons in the frame ((k, 2) m each)."""
    extra = {"plots": plots, "area_polygons": area}
    if offset != "auto":
        s = score_against_reference(updates, samples, cfg, time_offset_s=float(offset), **extra)
        return {**scores_dict(s), "time_offset": {"mode": "given", "applied_s": float(offset)}}
    first = score_against_reference(updates, samples, cfg, **extra)
    a = first.association
    lead = along_track_lead(a.err_x, a.err_y, a.vx, a.vy, cfg.min_offset_speed)
    info = {"mode": "auto", "lead_samples": len(lead)}
    if len(lead) < MIN_LEAD_SAMPLES:
        info.update(applied_s=0.0, note=f"fewer than {MIN_LEAD_SAMPLES} moving updates")
        return {**scores_dict(first), "time_offset": info}
    q10, q50, q90 = np.percentile(lead, [10, 50, 90])
    offset_s = -round(float(q50), 3)
    info.update(lead_median_s=_num(q50, 3), lead_p10_s=_num(q10, 3), lead_p90_s=_num(q90, 3))
    info["applied_s"] = offset_s
    info["without_offset"] = {
        p: {
            "probability_of_update": _num(getattr(first, p).probability_of_update),
            "rms_m": _num(getattr(first, p).position.rms_m, 3),
            "p95_m": _num(getattr(first, p).position.p95_m, 3),
        }
        for p in PHASES
    }
    s = score_against_reference(updates, samples, cfg, time_offset_s=offset_s, **extra)
    return {**scores_dict(s), "time_offset": info}


def _cell(v, fmt: str) -> str:
    return "–" if v is None else format(v, fmt)


def reference_table(summary: dict, title: str = "scored against the reference"):
    """A rich Table of a ``reference`` summary: one row per phase, then one per phase in
    the assessed area when there is one. "in": input-bound PoU; "PoU|in": PoU
    where the input reported."""
    from rich.table import Table

    t = Table(title=title)
    for col in ("phase", "aircraft", "PoU", "in", "PoU|in", "RMS m", "p95 m", "ids/ac",
                "changes", "dupl.", "false", "outside", "Mode-S"):  # fmt: skip
        t.add_column(col, justify="left" if col == "phase" else "right")
    for p in PHASES:
        d = summary.get(p)
        if d is None:
            continue
        ident = d["identity"]["mode_s"]
        t.add_row(
            p, str(d["aircraft"]), *_pou_cells(d),
            _cell(d["position"]["rms_m"], ".1f"), _cell(d["position"]["p95_m"], ".1f"),
            _cell(d["track_ids_per_aircraft"], ".2f"), str(d["id_changes"]),
            str(d["duplicate_tracks"]), str(d["false_tracks"]),
            str(d["outside_reference_tracks"]),
            "–" if not ident["checked"] else f"{ident['share']:.3f}",
        )  # fmt: skip
    for p in PHASES:
        a = (summary.get(p) or {}).get("area")
        if a is not None:
            t.add_row(f"{p} (area)", str(a["aircraft"]), *_pou_cells(a),
                      _cell(a["position"]["rms_m"], ".1f"), _cell(a["position"]["p95_m"], ".1f"),
                      *["" for _ in range(6)])  # fmt: skip
    return t


def _pou_cells(d: dict) -> tuple[str, str, str]:
    return (_cell(d["probability_of_update"], ".3f"), _cell(d.get("input_bound_pou"), ".3f"),
            _cell(d.get("pou_where_input"), ".3f"))  # fmt: skip


def print_table(summary: dict, title: str) -> None:
    """Print :func:`reference_table` (to stdout, plain when not a terminal)."""
    from rich.console import Console

    console = Console()
    if not console.is_terminal:
        console = Console(width=120)
    console.print(reference_table(summary, title))


def load_site_map(sites_file) -> dict:
    """Radar id → RadarSite from a sites TOML (``{}`` without one); InputError if bad."""
    from skyfuse.services.asterix import SitesError, load_sites
    from skyfuse.services.evaluation.inputs import InputError

    if sites_file is None:
        return {}
    try:
        return load_sites(sites_file)
    except (SitesError, OSError) as e:
        raise InputError(str(e), usage=True) from None


def open_reference(opts: ReferenceEvalOptions, date=None):
    """The reference recording of ``opts`` (its date: ``reference_date``, else ``date``)."""
    from skyfuse.services.evaluation.reference import read_reference

    return read_reference(
        opts.reference,
        date=opts.reference_date or date,
        kind=opts.reference_kind,
        sigma_m=opts.reference_sigma_m,
    )


def _checked(samples, updates, what: str) -> None:
    from skyfuse.services.evaluation.inputs import InputError

    hint = "give --sites with the sensor's position (CAT010 I042 is relative to it)"
    if not len(samples):
        raise InputError(f"{what}: no reference report could be placed: {hint}")
    if updates is not None and not len(updates):
        raise InputError(f"{what}: no track update could be placed: {hint}")


def evaluate_track_recording(path, reference, sites: dict, cfg, offset, area=()) -> dict:
    """Score the TrackBatch messages of an MCAP recording (no tracker) against
    ``reference`` (a ReferenceRecording; ``area``: the assessed area's AreaPolygons); the
    summary dict. The recording's plots are not the tracker's input as it was converted,
    so there is no input bound."""
    from skyfuse.services.evaluation.inputs import InputError, is_mcap
    from skyfuse.services.evaluation.observers import ReferenceObserver
    from skyfuse.services.evaluation.offline import OfflineConfig, run_offline
    from skyfuse.services.recording.mcap_io import ReadStats, iter_recording

    path = Path(path)
    if not path.is_file():
        raise InputError(f"tracks file: {str(path)!r} does not exist", usage=True)
    if not is_mcap(path):
        raise InputError(f"{path}: --tracks takes an MCAP recording with TrackBatch messages")
    obs = ReferenceObserver(reference, sites, cfg, offset, area=area)
    stats = ReadStats()
    msgs = (rec.message for rec in iter_recording(path, stats=stats))
    result = run_offline(msgs, None, OfflineConfig(tracker=None), [obs])
    if not result.counts["track batches"]:
        raise InputError(f"{path}: no TrackBatch messages (record a fusion service's output, "
                         "or skyfuse track --out)")  # fmt: skip
    return {"tracks_file": str(path), **result.summary(), "recording_rejected":
            dict(stats.rejected)}  # fmt: skip


def evaluate_sensor_tracks(path, reference, sites: dict, cfg, offset, *, date=None,
                           frame_kind="stereographic", area=()) -> dict:  # fmt: skip
    """Score a CAT010 file's own tracks against ``reference``; the frame is placed at the
    sensors' sites by the offline runner's rule (:func:`~skyfuse.services.fusion
    .system_frame.frame_for_sites`). The input bound counts the file's measured reports,
    confirmed or not (the sensor's own plots are not in the file); ``area``: the assessed
    area's AreaPolygons."""
    from skyfuse.fusion.frames import SystemFrame
    from skyfuse.services.evaluation.reference_area import area_in_frame
    from skyfuse.services.evaluation.sensor_tracks import read_sensor_tracks
    from skyfuse.services.fusion.system_frame import frame_for_sites

    tracks = read_sensor_tracks(path, date=date)
    used = [sites[s] for s in tracks.sensors if s in sites] or list(sites.values())
    spec = frame_for_sites(used, frame_kind)
    if spec is None:  # no site at all: the sensor gives WGS-84 (I041) or nothing
        lat = np.nanmean(tracks.positions.lat) if np.isfinite(tracks.positions.lat).any() else 0.0
        lon = np.nanmean(tracks.positions.lon) if np.isfinite(tracks.positions.lon).any() else 0.0
        spec = frame_for_sites([], frame_kind, float(lat), float(lon))
    frame = SystemFrame.from_spec(spec)
    updates = tracks.updates(frame, sites)
    samples = reference.samples(frame, sites)
    _checked(samples, updates, str(path))
    scores = score_reference(updates, samples, cfg, offset, plots=tracks.plots(frame, sites),
                             area=area_in_frame(list(area), frame))  # fmt: skip
    return {
        "sensor_tracks": tracks.summary(),
        "frame": spec.model_dump(mode="json"),
        "reference": {"reference_file": reference.summary(), **scores},
    }


def run_reference(args) -> int:
    """``skyfuse eval --tracks T.mcap | --sensor-tracks S.ast --reference REF``."""
    from skyfuse.services.evaluation.inputs import InputError
    from skyfuse.services.evaluation.report import STDOUT, write_summary
    from skyfuse.services.runtime.config import ConfigError, build_config

    opts = build_config(ReferenceEvalOptions, args)
    cfg = build_config(ReferenceScoreConfig, args)
    if opts.reference is None:
        raise ConfigError("--tracks / --sensor-tracks score against a reference: give "
                          "--reference FILE (ADS-B CAT021 or multilateration CAT010)")  # fmt: skip
    if opts.tracks is not None and opts.sensor_tracks is not None:
        raise ConfigError("give --tracks or --sensor-tracks, not both")
    date = getattr(args, "date", None)
    try:
        from skyfuse.services.evaluation.reference_area import area_summary, read_score_area

        area = read_score_area(opts.score_area)
        sites = load_site_map(getattr(args, "sites", None))
        ref = open_reference(opts, date)
        offset = opts.reference_time_offset
        if opts.tracks is not None:
            summary = evaluate_track_recording(opts.tracks, ref, sites, cfg, offset, area)
            title = f"{opts.tracks.name} against {ref.path.name}"
        else:
            summary = evaluate_sensor_tracks(opts.sensor_tracks, ref, sites, cfg, offset,
                                             date=date, area=area)  # fmt: skip
            summary["reference"]["score_area"] = area_summary(area, cfg)
            title = f"{opts.sensor_tracks.name} (sensor tracks) against {ref.path.name}"
    except InputError as e:
        if e.usage:
            raise ConfigError(str(e)) from None
        log.error("%s", e)
        return 1
    summary["reference_config"] = cfg.model_dump(mode="json")
    json_out = getattr(args, "json_out", None)
    if json_out is None or str(json_out) != STDOUT:
        print_table(summary["reference"], title)
    write_summary(summary, json_out)
    return 0
