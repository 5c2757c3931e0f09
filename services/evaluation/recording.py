"""``skyfuse eval FILE.mcap --tracker ...``: evaluate one tracker on a recording.

The recording's plot batches go through the same pipeline as ``skyfuse track`` and the
live fusion service (convert to the system frame → :class:`~fusion.tracker.Tracker`).
Truth comes from the recording itself:

* **plot labels** — simulated recordings carry each plot's origin ``target_id`` (−1 for
  clutter); real recordings carry Mode-S addresses (``mode_s``). Each plot gets the id
  of the track whose most likely plot it was (``TrackerOutput.assigned_plot``) and that
  track's confirmation state, and :func:`fusion.metrics.label_metrics.label_metrics`
  gives completeness, track-id changes per aircraft, confirmed false tracks per hour and
  the mean time to confirm (issue 6 §1, last item).
* **Truth messages** (simulated recordings): at every Truth time, the confirmed tracks of
  the latest output, predicted (constant velocity) to that time, against the targets that
  had a plot within ``coverage_window`` seconds (targets no radar sees are not "missed"):
  GOSPA (α = 2, cut-off ``gospa_c``, with the track-switch term counted) over time.
"""

from __future__ import annotations

import json
import logging
import time
from pathlib import Path

import numpy as np
from pydantic import BaseModel, Field
from skyfuse.schemas import PlotBatch, RadarSite, Truth

log = logging.getLogger(__name__)


class RecordingEvalOptions(BaseModel):
    """Evaluation options of a recording (the tracker is a ``TrackerConfig``)."""

    frame: str = Field("stereographic", description="System frame: stereographic or ned")
    gospa_c: float = Field(500.0, gt=0, description="GOSPA cut-off c, m")
    gospa_p: float = Field(2.0, ge=1, description="GOSPA order p")
    switch_penalty: float = Field(0.0, ge=0, description="GOSPA switch penalty γ, m")
    coverage_window: float = Field(15.0, gt=0, description="Target seen if a plot within, s")
    warmup_s: float = Field(
        30.0, ge=0, description="Aircraft first seen earlier: no time-to-confirm"
    )


def evaluate_recording(path: Path, tcfg, opts: RecordingEvalOptions | None = None) -> dict:
    """Run ``tcfg`` over the recording at ``path``; return the summary dict."""
    from skyfuse.fusion.frames import SystemFrame
    from skyfuse.fusion.metrics.gospa import gospa_over_time
    from skyfuse.fusion.metrics.label_metrics import label_metrics
    from skyfuse.services.cli.cmd_track import _scan_recording
    from skyfuse.services.fusion.pipeline import TrackPipeline
    from skyfuse.services.recording.mcap_io import iter_recording

    opts = opts or RecordingEvalOptions()
    sites, _ = _scan_recording(path)
    if not sites:
        raise ValueError(f"{path}: no radar site messages: cannot convert plots")
    lat0 = float(np.mean([s.lat for s in sites.values()]))
    lon0 = float(np.mean([s.lon for s in sites.values()]))
    frame = SystemFrame(opts.frame, lat0, lon0, 0.0)
    pipe = TrackPipeline(frame, tcfg)
    p_time, p_label, p_track, p_conf = [], [], [], []
    label_kind = None
    last_plot: dict[int, int] = {}
    last = None
    g_truth_ids, g_truth_pos, g_trk_ids, g_trk_pos = [], [], [], []
    batches = rejected = 0
    cpu = 0.0
    t_wall = time.perf_counter()
    for rec in iter_recording(path):
        msg = rec.message
        if isinstance(msg, RadarSite):
            sites[msg.radar_id] = msg
        elif isinstance(msg, PlotBatch):
            site = sites.get(msg.radar_id)
            if site is None:
                continue
            t0 = time.process_time()
            try:
                out = pipe.step(site, msg)
            except ValueError as e:
                rejected += 1
                log.warning("batch %s/%s rejected: %s", msg.radar_id, msg.seq, e)
                continue
            cpu += time.process_time() - t0
            batches += 1
            last = out
            b = out.batch
            tid = msg.column("target_id")
            mode_s = msg.column("mode_s")
            if tid is not None:
                lab_all, label_kind = np.asarray(tid, dtype=np.int64), "target_id"
            elif mode_s is not None:
                ms = np.asarray([-1 if v is None else v for v in msg.mode_s], dtype=np.int64)
                lab_all, label_kind = ms, label_kind or "mode_s"
            else:
                lab_all = np.full(len(msg), -1, dtype=np.int64)
            idx = np.asarray(b.plot_ids, dtype=np.int64) if b.plot_ids is not None else None
            lab = lab_all[idx] if idx is not None else lab_all[: len(b)]
            m = len(b)
            trk = np.full(m, -1, dtype=np.int64)
            conf = np.zeros(m, dtype=bool)
            rows = np.flatnonzero(out.assigned_plot >= 0)
            trk[out.assigned_plot[rows]] = out.ids[rows]
            conf[out.assigned_plot[rows]] = out.confirmed[rows]
            times = b.plot_times if b.plot_times is not None else np.full(m, b.time_ns)
            p_time.append(np.asarray(times, dtype=np.int64))
            p_label.append(lab)
            p_track.append(trk)
            p_conf.append(conf)
            if tid is not None:
                for t in np.unique(lab[lab >= 0]).tolist():
                    last_plot[int(t)] = int(b.time_ns)
        elif isinstance(msg, Truth) and last is not None:
            ids = np.asarray(msg.target_id, dtype=np.int64)
            seen = np.array(
                [0 <= msg.time - last_plot.get(int(t), -(10**30)) <= opts.coverage_window * 1e9
                 for t in ids], dtype=bool,
            )  # fmt: skip
            if len(ids):
                x, y, _ = frame.from_geodetic(
                    np.asarray(msg.lat), np.asarray(msg.lon), np.asarray(msg.alt)
                )
                pos = np.column_stack([x, y])[seen]
            else:
                pos = np.zeros((0, 2))
            c = np.flatnonzero(last.confirmed)
            dt = (msg.time - last.time_ns) * 1e-9
            st = last.states[c]
            tp = np.column_stack([st[:, 0] + st[:, 1] * dt, st[:, 2] + st[:, 3] * dt])
            g_truth_ids.append(ids[seen])
            g_truth_pos.append(pos)
            g_trk_ids.append(last.ids[c].astype(np.int64))
            g_trk_pos.append(tp)
    cat = np.concatenate
    t = cat(p_time) * 1e-9 if p_time else np.zeros(0)
    lm = label_metrics(
        t,
        cat(p_label) if p_label else np.zeros(0, np.int64),
        cat(p_track) if p_track else np.zeros(0, np.int64),
        cat(p_conf) if p_conf else np.zeros(0, bool),
        warmup_s=opts.warmup_s,
    )

    def num(v: float) -> float | None:
        return None if not np.isfinite(v) else round(float(v), 4)

    summary: dict = {
        "file": str(path),
        "tracker": tcfg.tracker,
        "depth": tcfg.memory_depth,
        "radars": sorted(sites),
        "batches": batches,
        "batches_rejected": rejected,
        "labels": label_kind,
        "label_metrics": {
            "aircraft": len(lm.aircraft),
            "completeness": num(lm.completeness),
            "mean_id_changes": num(lm.mean_id_changes),
            "confirmed_tracks": len(lm.confirmed_tracks),
            "false_tracks": len(lm.false_tracks),
            "false_per_hour": num(lm.false_per_hour),
            "mean_time_to_confirm_s": num(lm.mean_time_to_confirm),
            "duration_s": num(lm.duration_s),
        },
        "cpu_s": round(cpu, 3),
        "wall_s": round(time.perf_counter() - t_wall, 2),
        "config": tcfg.model_dump(mode="json"),
        "options": opts.model_dump(mode="json"),
    }
    if g_truth_ids:
        g = gospa_over_time(
            g_truth_ids, g_truth_pos, g_trk_ids, g_trk_pos,
            c=opts.gospa_c, p=opts.gospa_p, switch_penalty=opts.switch_penalty,
        )  # fmt: skip
        summary["gospa"] = {
            "samples": len(g_truth_ids),
            "mean_m": round(float(np.mean(g.distance)), 2),
            "mean_localisation": round(float(np.mean(g.localisation)), 2),
            "mean_missed": round(float(np.mean(g.missed)), 2),
            "mean_false": round(float(np.mean(g.false)), 2),
            "missed_targets_mean": round(float(np.mean(g.n_missed)), 3),
            "false_tracks_mean": round(float(np.mean(g.n_false)), 3),
            "full_switches": int(g.full_switches.sum()),
            "half_switches": int(g.half_switches.sum()),
            "total_m": round(g.total, 2),
        }
    return summary


def run_recording(args) -> int:
    """``skyfuse eval FILE.mcap``: tracker from ``--config`` [tracker] and the flags."""
    from skyfuse.fusion.tracker import TrackerConfig
    from skyfuse.services.cli.config import ConfigError, build_config

    path = Path(args.scenario)
    if not path.exists():
        raise ConfigError(f"file: {str(path)!r} does not exist")
    tcfg = build_config(
        TrackerConfig,
        args,
        toml_path=getattr(args, "config", None),
        section="tracker",
        env_prefix="SKYFUSE_TRACKER_",
    )
    from skyfuse.services.cli.cmd_track import is_mcap

    if not is_mcap(path):
        return _run_asterix(path, tcfg, args)
    try:
        summary = evaluate_recording(path, tcfg)
    except ValueError as e:
        log.error("%s", e)
        return 1
    text = json.dumps(summary, indent=1)
    json_out = getattr(args, "json_out", None)
    if json_out:
        Path(json_out).parent.mkdir(parents=True, exist_ok=True)
        Path(json_out).write_text(text + "\n")
    short = {"batches": summary["batches"], **summary["label_metrics"]}
    if "gospa" in summary:
        short["gospa_mean_m"] = summary["gospa"]["mean_m"]
    short["wall_s"] = summary["wall_s"]
    print(json.dumps(short))
    return 0


def _run_asterix(path: Path, tcfg, args) -> int:
    """``skyfuse eval FILE.ast|FILE.pcap --sites sites.toml``: track a real ASTERIX
    recording and score it by the Mode-S addresses on its plots (label metrics)."""
    from skyfuse.services.asterix.sites import SitesError
    from skyfuse.services.cli.config import ConfigError
    from skyfuse.services.evaluation.asterix import evaluate_asterix

    sites = getattr(args, "sites", None)
    try:
        res = evaluate_asterix(path, sites=sites, date=getattr(args, "date", None),
                               tracker_cfg=tcfg)  # fmt: skip
    except SitesError as e:
        raise ConfigError(str(e)) from None
    except ValueError as e:
        log.error("%s", e)
        return 1
    json_out = getattr(args, "json_out", None)
    if json_out:
        Path(json_out).parent.mkdir(parents=True, exist_ok=True)
        Path(json_out).write_text(json.dumps(res, indent=1, default=str) + "\n")
    print(json.dumps(res["metrics"], default=str))
    return 0
