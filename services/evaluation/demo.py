"""``skyfuse demo``: the whole distributed system on one machine.

N simulated radars (scenario ``regional``), the fusion service and the recorder run as
**separate processes** (``skyfuse sensor`` / ``fusion`` / ``record``) talking over Zenoh
in peer mode on loopback: the demo process listens on one explicit endpoint
(``tcp/127.0.0.1:PORT``, multicast scouting off) and every child connects to it; peers
gossip, so plots go from the sensors straight to the fusion service and the recorder.

Sequence: start recorder and fusion → wait for their liveliness tokens → start the
sensors with a common ``--start-at`` (so all radars run in step) → live view from the
Status messages → when the sensors have finished, let the fusion service drain its
reorder buffer, then SIGTERM fusion and recorder → evaluate the recording
(:func:`evaluate_recording`): plots, confirmed tracks, GOSPA against the recorded truth,
latency, messages recorded; write the JSON summary and a PNG of tracks against truth.
"""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydantic import BaseModel, Field
from skyfuse.schemas import (
    FrameSpec,
    PlotBatch,
    RadarSite,
    Status,
    TrackBatch,
    TrackPicture,
    TrackStatus,
    Truth,
)
from skyfuse.services.recording.mcap_io import ReadStats, iter_recording

log = logging.getLogger(__name__)


class DemoConfig(BaseModel):
    radars: int = Field(3, ge=1, le=4, description="Number of simulated radars (1-4)")
    targets: int = Field(12, ge=0, le=500, description="Number of aircraft")
    duration: float = Field(60.0, gt=0, le=86_400, description="Simulated duration, s")
    speed: float = Field(10.0, gt=0, le=100, description="Time scale: 10 = ten times faster")
    seed: int = Field(1, ge=0, description="Scenario seed")
    scenario: str = Field("regional", description="Scenario name")
    listen: str | None = Field(
        None, description="Endpoint the demo listens on (default tcp/127.0.0.1:<free port>)"
    )
    out: Path | None = Field(None, description="MCAP recording (default: in --workdir)")
    json_out: Path | None = Field(None, description="Write the JSON summary here")
    png: Path | None = Field(None, description="PNG of tracks vs truth (default: OUT.png)")
    workdir: Path | None = Field(None, description="Directory for logs (default: a temp dir)")
    foxglove: bool = Field(False, description="Serve a Foxglove WebSocket on 127.0.0.1")
    foxglove_port: int = Field(8765, ge=1, le=65535, description="Foxglove WebSocket port")
    reorder_wait: float = Field(0.5, ge=0, le=10, description="Fusion reorder wait, s")
    tracker: str = Field("lmits", description="Tracker kind for the fusion service")
    gospa_c: float = Field(2000.0, gt=0, description="GOSPA cut-off c, m")
    drain_timeout: float = Field(
        60.0, gt=0, le=3600, description="How long to let the fusion service catch up, s"
    )
    start_timeout: float = Field(
        60.0, gt=0, le=600, description="How long to wait for the services to start, s"
    )
    live: bool | None = Field(None, description="Live view (default: on a terminal)")


@dataclass
class Child:
    name: str
    args: list[str]
    log_path: Path
    proc: subprocess.Popen | None = None
    rc: int | None = None
    stop_s: float | None = None

    def start(self, cwd: Path | None = None) -> None:
        self._log = open(self.log_path, "wb")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "skyfuse.services.runtime.lifecycle", *self.args],
            stdin=subprocess.DEVNULL,
            stdout=self._log,
            stderr=subprocess.STDOUT,
            cwd=cwd,
            env=python_env(),
            start_new_session=True,  # a Ctrl-C on the terminal goes to the demo only
        )

    def poll(self) -> int | None:
        if self.proc is None:
            return None
        if self.rc is None:
            self.rc = self.proc.poll()
        return self.rc

    def terminate(self, timeout: float = 6.0) -> int | None:
        """SIGTERM, wait up to ``timeout`` s (then SIGKILL); return the exit code."""
        if self.proc is None:
            return None
        t0 = time.monotonic()
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                log.error("%s did not stop within %.0f s: killing it", self.name, timeout)
                self.proc.kill()
                self.proc.wait()
            self.stop_s = time.monotonic() - t0
        self.rc = self.proc.returncode
        self._log.close()
        return self.rc

    def tail(self, n: int = 15) -> str:
        try:
            lines = self.log_path.read_text(errors="replace").splitlines()
        except OSError:
            return ""
        return "\n".join(lines[-n:])


def python_env() -> dict[str, str]:
    """The environment for the children: this interpreter's import path."""
    env = dict(os.environ)
    root = str(Path(__file__).resolve().parents[1])
    env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


# --- evaluation of a recording ------------------------------------------------------------
@dataclass
class Evaluation:
    summary: dict
    truth_tracks: dict[int, list[tuple[float, float]]] = field(default_factory=dict)
    track_points: list[tuple[float, float]] = field(default_factory=list)
    sites: list[RadarSite] = field(default_factory=list)


def _track_xy(batch: TrackBatch, t: int, proj) -> np.ndarray:
    """Confirmed tracks of ``batch`` moved to time ``t`` (constant velocity), in the
    projection plane (x east, y north, m)."""
    conf = [tr for tr in batch.tracks if tr.status == TrackStatus.CONFIRMED]
    if not conf:
        return np.zeros((0, 2))
    lat = np.array([tr.lat for tr in conf])
    lon = np.array([tr.lon for tr in conf])
    x, y = proj.forward(lat, lon)
    dt = (t - np.array([tr.time for tr in conf])) / 1e9
    x = x + dt * np.array([tr.vel_east for tr in conf])
    y = y + dt * np.array([tr.vel_north for tr in conf])
    return np.column_stack([x, y])


def evaluate_recording(
    path: Path,
    frame: FrameSpec | None = None,
    gospa_c: float = 2000.0,
    min_detections: int = 3,
    window_s: float = 15.0,
) -> Evaluation:
    """Evaluate a demo recording: counts, tracks and GOSPA (horizontal, c = ``gospa_c`` m,
    p = 2, α = 2) between the recorded truth and the latest confirmed tracks at each truth
    time, moved to that time with their velocity.

    At truth time t, a target is *in coverage* if the recorded plots carry at least
    ``min_detections`` detections of it up to t (``PlotBatch.target_id``, simulation
    only), the last one within ``window_s`` s; GOSPA is over the targets in coverage. A
    target is *detectable* if it has ``min_detections`` detections in the whole run, and
    *confirmed* if a confirmed track was assigned to it (distance < c) at some truth time."""
    from skyfuse.fusion.frames import Stereographic
    from skyfuse.fusion.metrics.gospa import gospa

    stats = ReadStats()
    truths: list[Truth] = []
    batches: list[TrackBatch] = []
    picture = TrackPicture()
    sites: dict[str, RadarSite] = {}
    plot_batches = plots = 0
    det_ids: list[np.ndarray] = []
    det_times: list[np.ndarray] = []
    status_last: dict[str, Status] = {}
    topics: dict[str, int] = defaultdict(int)
    for rec in iter_recording(path, stats=stats):
        topics[rec.topic] += 1
        m = rec.message
        if isinstance(m, PlotBatch):
            plot_batches += 1
            plots += len(m.time)
            if m.target_id is not None and len(m.time):
                tid = m.column("target_id")
                det_ids.append(tid[tid >= 0])
                det_times.append(m.column("time")[tid >= 0])
        elif isinstance(m, TrackBatch):  # the feed's deltas and fulls, rebuilt
            if picture.apply(m):
                batches.append(picture.batch())
        elif isinstance(m, Truth):
            truths.append(m)
        elif isinstance(m, RadarSite):
            sites[m.radar_id] = m
        elif isinstance(m, Status):
            status_last[rec.topic] = m
    if frame is None:
        frame = batches[0].frame if batches else None
    lat0 = frame.lat0 if frame else (truths[0].lat[0] if truths and truths[0].lat else 0.0)
    lon0 = frame.lon0 if frame else (truths[0].lon[0] if truths and truths[0].lon else 0.0)
    proj = Stereographic(lat0, lon0)
    batches.sort(key=lambda b: b.time)
    bt = np.array([b.time for b in batches], dtype=np.int64)
    d_ids = np.concatenate(det_ids) if det_ids else np.zeros(0, np.int64)
    d_t = np.concatenate(det_times) if det_times else np.zeros(0, np.int64)
    order = np.argsort(d_t, kind="stable")
    d_ids, d_t = d_ids[order], d_t[order]
    window_ns = int(window_s * 1e9)

    def in_coverage(t: int, ids: list[int]) -> np.ndarray:
        """Targets detected >= min_detections times up to t, the last within window_s."""
        k = int(np.searchsorted(d_t, t, side="right"))
        upto_ids, upto_t = d_ids[:k], d_t[:k]
        out = np.zeros(len(ids), dtype=bool)
        for j, tid in enumerate(ids):
            mask = upto_ids == tid
            n = int(mask.sum())
            out[j] = n >= min_detections and upto_t[mask][-1] > t - window_ns
        return out

    detectable = {int(t) for t in np.unique(d_ids) if (d_ids == t).sum() >= min_detections}
    confirmed_targets: set[int] = set()
    per_time = []
    truth_tracks: dict[int, list[tuple[float, float]]] = defaultdict(list)
    for tr in truths:
        for tid, la, lo in zip(tr.target_id, tr.lat, tr.lon):
            truth_tracks[tid].append((lo, la))
        ids = np.array(tr.target_id, dtype=np.int64)
        keep = in_coverage(tr.time, tr.target_id)
        if not keep.any() or len(bt) == 0:
            continue
        k = int(np.searchsorted(bt, tr.time, side="right")) - 1
        if k < 0:
            continue
        x, y = proj.forward(np.asarray(tr.lat)[keep], np.asarray(tr.lon)[keep])
        est = _track_xy(batches[k], tr.time, proj)
        res = gospa(np.column_stack([x, y]), est, c=gospa_c, p=2.0, alpha=2.0)
        assigned = ids[keep][res.assignment >= 0]
        confirmed_targets.update(int(a) for a in assigned)
        per_time.append((tr.time, res.distance, res.n_missed, res.n_false, len(est)))
    track_points = []
    for b in batches[:: max(1, len(batches) // 400)]:
        track_points += [(t.lon, t.lat) for t in b.tracks if t.status == TrackStatus.CONFIRMED]
    final = batches[-1] if batches else None
    fusion_status = next(
        (s for k, s in status_last.items() if "/fusion/" in k), None
    )  # the last one published (after the final flush)
    sensor_batches = sum(
        s.counters.get("batches", 0) for s in status_last.values() if s.service == "sensor"
    )
    g = np.array([p[1] for p in per_time]) if per_time else np.zeros(0)
    half = g[len(g) // 2 :]
    summary = {
        "recording": str(path),
        "recording_truncated": stats.truncated,
        "recording_rejected": dict(stats.rejected),
        "messages_recorded": int(sum(topics.values())),
        "messages_by_topic": dict(sorted(topics.items())),
        "radars": sorted(sites),
        "plot_batches_recorded": plot_batches,
        "plot_batches_published": sensor_batches,
        "plots_recorded": plots,
        "fusion_plots_in": fusion_status.counters.get("plots_in") if fusion_status else None,
        "fusion_batches_in": fusion_status.counters.get("batches_in") if fusion_status else None,
        "fusion_cycles": fusion_status.counters.get("cycles") if fusion_status else None,
        "fusion_rejected": dict(fusion_status.rejected) if fusion_status else None,
        "track_batches": len(batches),
        "confirmed_tracks_final": (
            sum(t.status == TrackStatus.CONFIRMED for t in final.tracks) if final else 0
        ),
        "confirmed_track_ids": len(
            {t.track_id for b in batches for t in b.tracks if t.status == TrackStatus.CONFIRMED}
        ),
        "targets_truth": len({t for tr in truths for t in tr.target_id}),
        "targets_detectable": len(detectable),
        "targets_confirmed": len(confirmed_targets & detectable),
        "gospa_c_m": gospa_c,
        "gospa_mean_m": float(g.mean()) if g.size else None,
        "gospa_mean_second_half_m": float(half.mean()) if half.size else None,
        "gospa_final_m": float(g[-1]) if g.size else None,
        "gospa_final_missed": per_time[-1][2] if per_time else None,
        "gospa_final_false": per_time[-1][3] if per_time else None,
        "latency_ms": (
            fusion_status.latency_ms.model_dump(exclude_none=True)
            if fusion_status and fusion_status.latency_ms
            else None
        ),
    }
    return Evaluation(summary, dict(truth_tracks), track_points, list(sites.values()))


def plot_tracks_vs_truth(ev: Evaluation, path: Path, title: str = "skyfuse demo") -> None:
    """PNG: truth trajectories (lines), confirmed track positions (dots), radar sites."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 8), dpi=110)
    for i, (_tid, pts) in enumerate(sorted(ev.truth_tracks.items())):
        a = np.asarray(pts)
        ax.plot(
            a[:, 0], a[:, 1], "-", color="k", lw=0.8, zorder=3, label="truth" if i == 0 else None
        )
    if ev.track_points:
        a = np.asarray(ev.track_points)
        ax.plot(a[:, 0], a[:, 1], ".", ms=4, color="tab:blue", alpha=0.5, label="confirmed tracks")
    for s in ev.sites:
        ax.plot(s.lon, s.lat, "^", color="tab:red", ms=9)
        ax.annotate(s.radar_id, (s.lon, s.lat), textcoords="offset points", xytext=(5, 5))
    sm = ev.summary
    ax.set_title(
        f"{title}: {sm['targets_confirmed']}/{sm['targets_detectable']} targets confirmed, "
        f"mean GOSPA {sm['gospa_mean_m'] or float('nan'):.0f} m"
    )
    ax.set_xlabel("longitude °")
    ax.set_ylabel("latitude °")
    ax.set_aspect(1 / np.cos(np.radians(np.mean([s.lat for s in ev.sites]) if ev.sites else 0)))
    ax.grid(alpha=0.3)
    ax.legend(loc="best")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
