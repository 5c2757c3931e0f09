"""``skyfuse track FILE.mcap|FILE.pcap|FILE.ast``: run the tracker offline over a recording.

Reads the radar sites (``skyfuse/@v1/radar/*/site``) and plot batches
(``…/plots``) of a recording (simulated or real), applies the batches in time order
through the same pipeline as the live fusion service (convert to the system frame →
tracker → TrackBatch/TrackEvent), and writes the tracks and events to an MCAP file on
``skyfuse/@v1/fusion/{id}/tracks`` and ``…/events``. With ``--json`` it writes a summary:
plots and batches processed, confirmed and false tracks, and — when the recording holds
simulation truth (``skyfuse/@v1/sim/truth``; plots carry ``target_id``) — the truth
coverage and position error, plus timing.

An ASTERIX recording (CAT048 plots with CAT034 service messages; pcap of UDP or a raw
``.ast`` file, told apart from MCAP by its first bytes) is decoded with
:func:`services.asterix.read_asterix` (``--sites`` TOML, ``--date`` of the first record)
and its sector batches go through the same pipeline; its summary adds the reader's
counts and the Mode-S label metrics (completeness, track-id changes, confirmed false
tracks per hour, time to confirm: :mod:`services.eval_asterix`). Plots without a flight
level (primary-only) get ``--assumed-altitude`` (default 3000 m for ASTERIX, ± 3000 m).

Examples::

    skyfuse track r.mcap --tracker lmits --depth 3 --out t.mcap --json t.json
    skyfuse track r.mcap --config fusion.toml --frame ned        # [tracker] table
    skyfuse track rec.pcap --sites sites.toml --date 2024-05-17 --tracker lmits --depth 3 \
        --out t.mcap --json t.json
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import logging
import time
from collections import Counter, defaultdict
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, Field
from skyfuse.schemas import PlotBatch, RadarSite, TrackBatch, TrackEvent, Truth, keys
from skyfuse.services.cli.config import ConfigError, add_model_arguments, build_config
from skyfuse.services.cli.progress import progress_bar
from skyfuse.services.evaluation.asterix import LABEL_WARMUP_S, PlotTrackRows, rejection_reasons
from skyfuse.services.recording.mcap_io import (
    SCHEMA_PREFIX,
    ReadStats,
    RecordingWriter,
    iter_recording,
    json_schema_bytes,
)

log = logging.getLogger(__name__)


class TrackCommandConfig(BaseModel):
    """Options of ``skyfuse track`` (the tracker itself is ``[tracker]`` / TrackerConfig)."""

    file: Path = Field(
        description="Input recording: MCAP with sites and plot batches, or ASTERIX CAT048/CAT034 "
        "(.pcap of UDP, raw .ast)"
    )
    out: Path = Field(Path("tracks.mcap"), description="Output MCAP with tracks and events")
    json_summary: Path | None = Field(None, description="Write a JSON summary to this file")
    frame: Literal["stereographic", "ned"] = Field(
        "stereographic", description="System frame, centred on the mean of the radar sites"
    )
    fusion_id: str = Field("main", description="Fusion id of the output topics")
    publish: Literal["confirmed", "all"] = Field(
        "confirmed", description="Tracks in each TrackBatch: confirmed or all"
    )
    progress: bool | None = Field(None, description="Show a progress bar (default: on a terminal)")
    coverage_window: float = Field(
        15.0, gt=0, description="A target counts as inside coverage this long after a plot, s"
    )
    sites: Path | None = Field(
        None, description="ASTERIX: sites TOML ([[radar]] sac, sic, lat, lon, alt, ...)"
    )
    date: dt.date | None = Field(
        None,
        description="ASTERIX: UTC date of the first record, YYYY-MM-DD (default: pcap capture "
        "time, else today)",
    )
    sector_count: int = Field(
        16, ge=1, le=360, description="ASTERIX: fixed sectors per turn for radars without CAT034"
    )
    assumed_altitude: float | None = Field(
        None,
        ge=-1000,
        le=30000,
        description="Height assumed for plots without altitude/elevation, m, ± 3000 m (default: "
        "3000 for ASTERIX input, none for MCAP: such plots are rejected)",
    )


def _tracker_config_model():
    from skyfuse.fusion.tracker import TrackerConfig

    return TrackerConfig


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "track",
        help="run the tracker over a recording and write tracks/events (MCAP)",
        description=__doc__.split("\n\n")[0],
    )
    add_model_arguments(p, TrackCommandConfig, positional=("file",), skip=("json_summary",))
    p.add_argument(
        "--json",
        dest="json_summary",
        default=argparse.SUPPRESS,
        help="Write a JSON summary to this file",
    )
    p.add_argument("--config", type=Path, default=None, help="TOML file with a [tracker] table")
    group = p.add_argument_group("tracker")
    add_model_arguments(group, _tracker_config_model())
    p.set_defaults(func=run)


def _scan_recording(path: Path) -> tuple[dict[str, RadarSite], int]:
    """First pass: the radar sites and the number of plot batches."""
    sites: dict[str, RadarSite] = {}
    n_batches = 0
    for rec in iter_recording(path, decode=False):
        if rec.topic.startswith(keys.PREFIX + "/radar/"):
            if rec.topic.endswith("/site"):
                try:
                    site = RadarSite.from_json_bytes(rec.data)
                except ValueError as e:
                    log.warning("skipping invalid site on %s: %s", rec.topic, e)
                    continue
                sites.setdefault(site.radar_id, site)
            elif rec.topic.endswith("/plots"):
                n_batches += 1
    return sites, n_batches


class Evaluation:
    """Truth-based measures from the plots' ``target_id`` (evaluation only).

    A track's label is the target whose plots it took most often (as the most likely
    plot of a batch); ``-1`` (clutter) or no plot at all makes a confirmed track false.
    Truth coverage: at each Truth message, the fraction of targets with a plot in the
    last ``window`` seconds (inside coverage) that have a live confirmed track labelled
    with them; the position error of that track is accumulated for the RMSE. The
    "after acquisition" variant leaves out each target's first 2 × window seconds."""

    def __init__(self, frame, window_s: float) -> None:
        self.frame = frame
        self.window = int(window_s * 1e9)
        self.labels: dict[int, Counter] = defaultdict(Counter)
        self.confirmed_ever: set[int] = set()
        self.last_plot: dict[int, int] = {}
        self.first_plot: dict[int, int] = {}
        self.settled_samples = 0
        self.settled_covered = 0
        self.plots_by_target: Counter = Counter()
        self.target_plots = 0
        self.clutter_plots = 0
        self.assigned_target_plots = 0
        self.samples = 0
        self.covered = 0
        self.sq_err: list[float] = []
        self.has_truth = False
        self.targets_in_coverage: set[int] = set()
        self.targets_covered: set[int] = set()
        self.last = None

    def label(self, tid: int) -> int:
        c = self.labels.get(tid)
        return c.most_common(1)[0][0] if c else -1

    def on_output(self, out) -> None:
        self.last = out
        tids = out.batch.target_ids
        self.confirmed_ever.update(out.ids[out.confirmed].tolist())
        if tids is None:
            return
        self.target_plots += int((tids >= 0).sum())
        self.clutter_plots += int((tids < 0).sum())
        for t in np.unique(tids[tids >= 0]):
            self.last_plot[int(t)] = out.time_ns
            self.first_plot.setdefault(int(t), out.time_ns)
            self.plots_by_target[int(t)] += 1
        rows = np.flatnonzero(out.assigned_plot >= 0)
        for r in rows:
            t = int(tids[out.assigned_plot[r]])
            self.labels[int(out.ids[r])][t] += 1
            if t >= 0 and out.confirmed[r]:
                self.assigned_target_plots += 1

    def on_truth(self, truth: Truth) -> None:
        self.has_truth = True
        out = self.last
        if out is None or not truth.target_id:
            return
        inside = [
            i
            for i, t in enumerate(truth.target_id)
            if t in self.last_plot and 0 <= truth.time - self.last_plot[t] <= self.window
        ]
        if not inside:
            return
        conf = np.flatnonzero(out.confirmed)
        by_label: dict[int, list[int]] = defaultdict(list)
        for r in conf:
            by_label[self.label(int(out.ids[r]))].append(r)
        tx, ty, _ = self.frame.from_geodetic(
            np.asarray(truth.lat), np.asarray(truth.lon), np.asarray(truth.alt)
        )
        dt = (truth.time - out.time_ns) * 1e-9
        for i in inside:
            t = truth.target_id[i]
            self.samples += 1
            settled = truth.time - self.first_plot[t] > 2 * self.window
            self.settled_samples += settled
            self.targets_in_coverage.add(t)
            rows = by_label.get(t)
            if not rows:
                continue
            self.covered += 1
            self.settled_covered += settled
            self.targets_covered.add(t)
            x = out.states[rows]
            px = x[:, 0] + x[:, 1] * dt
            py = x[:, 2] + x[:, 3] * dt
            self.sq_err.append(float(np.min((px - tx[i]) ** 2 + (py - ty[i]) ** 2)))

    def summary(self) -> dict:
        false = sorted(i for i in self.confirmed_ever if self.label(i) < 0)
        per_target = Counter(self.label(i) for i in self.confirmed_ever if self.label(i) >= 0)
        seen = {t for t, n in self.plots_by_target.items() if n >= 3}
        res = {
            "tracks_confirmed": len(self.confirmed_ever),
            "false_tracks": len(false),
            "false_track_ids": false[:50],
            "targets_with_plots": len(seen),
            "targets_with_confirmed_track": len(seen & set(per_target)),
            "confirmed_tracks_per_target_mean": (
                round(float(np.mean(list(per_target.values()))), 3) if per_target else None
            ),
            "target_plots": self.target_plots,
            "clutter_plots": self.clutter_plots,
            "target_plots_on_confirmed_tracks": self.assigned_target_plots,
        }
        if self.has_truth:
            res["truth_coverage"] = round(self.covered / self.samples, 4) if self.samples else None
            res["truth_samples_inside_coverage"] = self.samples
            # the same, leaving out each target's first 2 × window after its first plot
            res["truth_coverage_after_acquisition"] = (
                round(self.settled_covered / self.settled_samples, 4)
                if self.settled_samples
                else None
            )
            res["position_rmse_m"] = (
                round(float(np.sqrt(np.mean(self.sq_err))), 1) if self.sq_err else None
            )
        return res


ASTERIX_ASSUMED_ALTITUDE_M = 3000.0
"""Height given to ASTERIX plots without a flight level (primary-only), m (± 3000 m)."""


def is_mcap(path: Path) -> bool:
    """True when the file starts with the MCAP magic (else: ASTERIX pcap or raw)."""
    with open(path, "rb") as f:
        return f.read(5) == b"\x89MCAP"


def _truth_summary(ev: Evaluation, *, asterix: bool) -> dict:
    """``ev.summary()``; ASTERIX plots carry no ``target_id``, so only the track count
    is kept (the Mode-S label metrics are the evaluation there)."""
    res = ev.summary()
    return {"tracks_confirmed": res["tracks_confirmed"]} if asterix else res


def _read_asterix_input(cfg: TrackCommandConfig):
    from skyfuse.services.asterix import SitesError, load_sites, read_asterix

    try:
        sites = load_sites(cfg.sites) if cfg.sites is not None else None
    except (SitesError, OSError) as e:
        raise ConfigError(str(e)) from None
    try:
        res = read_asterix(cfg.file, date=cfg.date, sites=sites, sector_count=cfg.sector_count)
    except ValueError as e:
        raise ConfigError(f"file: {e}") from None
    for text in res.messages[:10]:
        log.info("asterix: %s", text)
    log.info(
        "%s: %d plots in %d batches from %d radars (%s)",
        cfg.file,
        res.n_plots,
        len(res.batches),
        len(res.radars),
        ", ".join(f"{r} {n}" for r, n in res.radars.items()),
    )
    return res


def run(args: argparse.Namespace) -> int:
    from skyfuse.fusion.frames import SystemFrame
    from skyfuse.services.fusion.pipeline import TrackPipeline

    cfg = build_config(TrackCommandConfig, args)
    tcfg = build_config(
        _tracker_config_model(),
        args,
        toml_path=getattr(args, "config", None),
        section="tracker",
        env_prefix="SKYFUSE_TRACKER_",
    )
    keys.check_id(cfg.fusion_id, "fusion id")
    if not cfg.file.exists():
        raise ConfigError(f"file: {str(cfg.file)!r} does not exist")
    ax = None
    if is_mcap(cfg.file):
        for name in ("sites", "date"):
            if getattr(cfg, name) is not None:
                log.warning("--%s applies to ASTERIX input only: ignored for MCAP", name)
        sites, n_batches = _scan_recording(cfg.file)
        if not sites:
            log.error("%s: no radar site messages: cannot convert plots", cfg.file)
            return 1
    else:
        ax = _read_asterix_input(cfg)
        sites, n_batches = dict(ax.sites), len(ax.batches)
        if not sites:
            log.error(
                "%s: no radar has a site (radars: %s): give --sites with their positions",
                cfg.file,
                ", ".join(ax.radars) or "none",
            )
            return 1
    assumed = cfg.assumed_altitude
    if assumed is None and ax is not None:
        assumed = ASTERIX_ASSUMED_ALTITUDE_M
    lat0 = float(np.mean([s.lat for s in sites.values()]))
    lon0 = float(np.mean([s.lon for s in sites.values()]))
    frame = SystemFrame(cfg.frame, lat0, lon0, 0.0)
    pipe = TrackPipeline(
        frame, tcfg, fusion_id=cfg.fusion_id, publish=cfg.publish, assumed_altitude=assumed
    )
    ev = Evaluation(frame, cfg.coverage_window)
    rows = PlotTrackRows() if ax is not None else None
    stats = ReadStats()
    counts: Counter = Counter()
    step_ms: list[float] = []
    last_time = None
    tracks_topic = keys.fusion_tracks(cfg.fusion_id)
    events_topic = keys.fusion_events(cfg.fusion_id)
    t_start = time.perf_counter()
    meta = {
        "command": "skyfuse track",
        "source": str(cfg.file),
        "frame": frame.spec().model_dump_json(),
        "tracker": tcfg.model_dump_json(),
    }
    with (
        RecordingWriter(cfg.out, metadata=meta) as writer,
        progress_bar(f"track {cfg.file.name}", n_batches, enabled=cfg.progress) as advance,
    ):
        # register the two channels once (their JSON Schemas are built once, not per write)
        tracks_ch = writer.channel_for(
            tracks_topic,
            schema_name=SCHEMA_PREFIX + "TrackBatch",
            schema_data=json_schema_bytes(TrackBatch),
        )
        events_ch = writer.channel_for(
            events_topic,
            schema_name=SCHEMA_PREFIX + "TrackEvent",
            schema_data=json_schema_bytes(TrackEvent),
        )
        if ax is not None:
            messages = iter(ax.batches)
        else:
            messages = (rec.message for rec in iter_recording(cfg.file, stats=stats))
        for msg in messages:
            if isinstance(msg, RadarSite):
                sites[msg.radar_id] = msg
            elif isinstance(msg, Truth):
                ev.on_truth(msg)
            elif isinstance(msg, PlotBatch):
                site = sites.get(msg.radar_id)
                advance(1)
                if site is None:
                    counts["batches without a site"] += 1
                    continue
                if last_time is not None and msg.time_end < last_time:
                    counts["batches out of time order"] += 1
                last_time = msg.time_end if last_time is None else max(last_time, msg.time_end)
                t0 = time.perf_counter()
                try:
                    out = pipe.step(site, msg)
                except ValueError as e:
                    counts["batches rejected"] += 1
                    log.warning("batch %s/%s rejected: %s", msg.radar_id, msg.seq, e)
                    continue
                tb = pipe.track_batch(out, msg)
                evs = pipe.track_events(out)
                step_ms.append((time.perf_counter() - t0) * 1e3)
                counts["batches"] += 1
                counts["plots"] += len(msg)
                ev.on_output(out)
                if rows is not None:
                    rows.add(msg, out)
                writer.write_raw(tracks_ch, tb.to_json_bytes(), msg.time_end)
                for e in evs:
                    writer.write_raw(events_ch, e.to_json_bytes(), e.time)
                    counts[f"events {e.kind.value}"] += 1
    wall = time.perf_counter() - t_start
    ms = np.asarray(step_ms) if step_ms else np.zeros(1)
    summary = {
        "file": str(cfg.file),
        "out": str(cfg.out),
        "tracker": tcfg.tracker,
        "depth": tcfg.memory_depth,
        "frame": frame.spec().model_dump(mode="json"),
        "radars": sorted(sites),
        "batches": counts["batches"],
        "plots_processed": counts["plots"],
        "plots_rejected": rejection_reasons(pipe.rejected),
        "counts": dict(counts),
        **_truth_summary(ev, asterix=ax is not None),
        "tracker_totals": dict(pipe.tracker.totals),
        "recording_rejected": dict(stats.rejected),
        "timing": {
            "wall_s": round(wall, 2),
            "ms_per_batch_mean": round(float(ms.mean()), 3),
            "ms_per_batch_p95": round(float(np.percentile(ms, 95)), 3),
            "ms_per_batch_max": round(float(ms.max()), 3),
            "plots_per_s": round(counts["plots"] / wall, 1) if wall > 0 else None,
        },
        "config": tcfg.model_dump(mode="json"),
    }
    if ax is not None:
        summary["asterix"] = {
            "radars": ax.radars,
            "scan_period_source": ax.scan_period_source,
            "assumed_altitude_m": assumed,
            "counts": ax.stats,
            "messages": ax.messages[:20],
        }
        summary["mode_s"] = rows.metrics(warmup_s=LABEL_WARMUP_S)
    text = json.dumps(summary, indent=2)
    if cfg.json_summary is not None:
        cfg.json_summary.write_text(text + "\n")
    short = {
        k: summary[k]
        for k in ("batches", "plots_processed", "tracks_confirmed", "false_tracks")
        if k in summary
    }
    for k in (
        "targets_with_plots",
        "targets_with_confirmed_track",
        "truth_coverage",
        "truth_coverage_after_acquisition",
        "position_rmse_m",
    ):
        if k in summary:
            short[k] = summary[k]
    if ax is not None:
        for k in ("aircraft", "completeness", "confirmed_false_tracks_per_hour"):
            short[k] = summary["mode_s"][k]
    short["wall_s"] = summary["timing"]["wall_s"]
    print(json.dumps(short))
    return 0
