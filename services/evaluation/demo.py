"""``skyfuse demo``: the whole distributed system on one machine.

N simulated radars (scenario ``regional``), the fusion service and the recorder run as
**separate processes** (``skyfuse sensor`` / ``fusion`` / ``record``) talking over Zenoh
in peer mode on loopback: the demo process listens on one explicit endpoint
(``tcp/127.0.0.1:PORT``, multicast scouting off) and every child connects to it; peers
gossip, so plots go from the sensors straight to the fusion service and the recorder.

Sequence: start recorder and fusion → wait for their liveliness tokens → start the
sensors with a common ``--start-at`` (so all radars run in step) → live view from the
Status messages → when the sensors have finished, let the fusion service drain its
reorder buffer, then SIGTERM fusion and recorder → report on the recording
(:func:`report_recording`): plots, confirmed tracks, GOSPA against the recorded truth,
latency, messages recorded, and the confirmed tracks by callsign when they carry
identities (:func:`identity_lines`); write the JSON summary and a PNG of tracks
against truth.
"""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import time
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydantic import BaseModel, Field
from skyfuse.schemas import PlotBatch, RadarSite, Status, TrackBatch, TrackStatus, Truth
from skyfuse.schemas.identity import mode_3a_text
from skyfuse.services.evaluation.observers import Coverage, TruthObserver
from skyfuse.services.evaluation.offline import Observer, OfflineConfig, run_offline
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
    json_out: Path | None = Field(
        None, description="Write the JSON summary to FILE (--json alone or -: to stdout)"
    )
    png: Path | None = Field(None, description="PNG of tracks vs truth (default: OUT.png)")
    workdir: Path | None = Field(None, description="Directory for logs (default: a temp dir)")
    foxglove: bool = Field(False, description="Serve a Foxglove WebSocket on 127.0.0.1")
    foxglove_port: int = Field(8765, ge=1, le=65535, description="Foxglove WebSocket port")
    reorder_wait: float = Field(0.5, ge=0, le=10, description="Fusion reorder wait, s")
    tracker: str = Field("lmits", description="Tracker kind for the fusion service")
    # the same flag, default and bounds as fusion.tracker.TrackerConfig.particles (not
    # imported here: the tracker's import would slow every ``skyfuse demo --help``)
    particles: int = Field(
        1000, ge=1, le=1_000_000, description="ipf/lmipf: particles per track N (source 1000)"
    )
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

    def start(self, cwd: Path | None = None, state_home: Path | None = None) -> None:
        """Start the child; ``state_home``: its ``XDG_STATE_HOME`` (the demo gives every
        run a fresh one, so that a sensor's progress or the fusion's saved picture from a
        previous demo is never resumed)."""
        self._log = open(self.log_path, "wb")
        env = python_env()
        if state_home is not None:
            env["XDG_STATE_HOME"] = str(state_home)
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "skyfuse.services.cli", *self.args],
            stdin=subprocess.DEVNULL,
            stdout=self._log,
            stderr=subprocess.STDOUT,
            cwd=cwd,
            env=env,
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
    """The environment for the children: this interpreter's import path for ``skyfuse``
    (the folders its namespace package comes from, first on ``PYTHONPATH``)."""
    import skyfuse

    env = dict(os.environ)
    roots = [str(Path(p).resolve().parent) for p in skyfuse.__path__]
    old = [env["PYTHONPATH"]] if env.get("PYTHONPATH") else []
    env["PYTHONPATH"] = os.pathsep.join(dict.fromkeys([*roots, *old]))
    return env


# --- the report of a demo recording ---------------------------------------------------
@dataclass
class DemoReport:
    """The demo's report: the summary dict and what the PNG draws (lon, lat degrees)."""

    summary: dict
    truth_tracks: dict[int, list[tuple[float, float]]] = field(default_factory=dict)
    track_points: list[tuple[float, float]] = field(default_factory=list)
    sites: list[RadarSite] = field(default_factory=list)


class _DemoObserver(Observer):
    """What the demo reports beyond the truth scores: plots recorded, the recorded
    tracks (counts, points for the PNG), the truth trajectories and the last Status of
    each service."""

    def __init__(self) -> None:
        self.plot_batches = self.plots = 0
        self.batches: list[TrackBatch] = []
        self.truth_tracks: dict[int, list[tuple[float, float]]] = defaultdict(list)
        self.status: dict[tuple[str, str], Status] = {}

    def on_plots(self, batch: PlotBatch) -> None:
        self.plot_batches += 1
        self.plots += len(batch.time)

    def on_tracks(self, tracks: TrackBatch) -> None:
        self.batches.append(tracks)

    def on_truth(self, truth: Truth) -> None:
        for tid, la, lo in zip(truth.target_id, truth.lat, truth.lon):
            self.truth_tracks[tid].append((lo, la))

    def on_message(self, msg) -> None:
        if isinstance(msg, Status):
            self.status[(msg.service, msg.service_id)] = msg  # the last one of each service

    def summary(self) -> dict:
        conf = TrackStatus.CONFIRMED
        final = self.batches[-1] if self.batches else None
        fusion = next((s for (svc, _), s in self.status.items() if svc == "fusion"), None)
        fc = fusion.counters if fusion else {}
        return {
            "plot_batches_recorded": self.plot_batches,
            "plot_batches_published": sum(
                s.counters.get("batches", 0) for (svc, _), s in self.status.items()
                if svc == "sensor"
            ),
            "plots_recorded": self.plots,
            "fusion_plots_in": fc.get("plots_in") if fusion else None,
            "fusion_batches_in": fc.get("batches_in") if fusion else None,
            "fusion_cycles": fc.get("cycles") if fusion else None,
            "fusion_rejected": dict(fusion.rejected) if fusion else None,
            "track_batches": len(self.batches),
            "confirmed_tracks_final": (
                sum(t.status == conf for t in final.tracks) if final else 0
            ),
            "confirmed_track_ids": len(
                {t.track_id for b in self.batches for t in b.tracks if t.status == conf}
            ),
            "latency_ms": (
                fusion.latency_ms.model_dump(exclude_none=True)
                if fusion and fusion.latency_ms
                else None
            ),
        }  # fmt: skip

    def tracks_by_callsign(self) -> dict[str, list[int]]:
        """The confirmed tracks of the run by the identity they showed: callsign, else
        ``squawk NNNN`` (octal) → sorted track ids (several ids: the aircraft's track
        changed id). Empty when no track had an identity."""
        ids: dict[str, set[int]] = defaultdict(set)
        for b in self.batches:
            for t in b.tracks:
                if t.status != TrackStatus.CONFIRMED:
                    continue
                name = t.callsign or (f"squawk {mode_3a_text(t.mode_3a)}" if t.mode_3a else "")
                if name:
                    ids[name].add(t.track_id)
        return {name: sorted(v) for name, v in sorted(ids.items())}

    def track_points(self, n: int = 400) -> list[tuple[float, float]]:
        """Confirmed track positions of about ``n`` TrackBatches (lon, lat)."""
        pts = []
        for b in self.batches[:: max(1, len(self.batches) // n)]:
            pts += [(t.lon, t.lat) for t in b.tracks if t.status == TrackStatus.CONFIRMED]
        return pts


_ORDER = {RadarSite: 0, PlotBatch: 1, TrackBatch: 2, Truth: 3}


def _scenario_order(path: Path, stats: ReadStats, topics: Counter) -> list:
    """The recording's messages in scenario time: the recorder stamps them with their
    arrival (wall clock), the scores compare the tracks of time t with the truth of t.
    Sites first; at equal times plots, then tracks, then truth."""
    keyed = []
    for i, rec in enumerate(iter_recording(path, stats=stats)):
        topics[rec.topic] += 1
        m = rec.message
        rank = _ORDER.get(type(m), 4)
        t = {1: "time_end", 2: "time", 3: "time"}.get(rank)
        keyed.append(((getattr(m, t) if t else -1, rank, i), m))
    keyed.sort(key=lambda k: k[0])
    return [m for _, m in keyed]


def report_recording(
    path: Path, gospa_c: float = 2000.0, min_detections: int = 3, window_s: float = 15.0
) -> DemoReport:
    """The report of a demo recording: the recorded tracks of the live fusion service
    scored against the recorded truth by the offline runner without a tracker
    (:func:`~skyfuse.services.evaluation.offline.run_offline` with ``tracker=None``):
    GOSPA (horizontal, c = ``gospa_c`` m, p = 2, α = 2) between the truth targets in
    coverage (:class:`~skyfuse.services.evaluation.observers.Coverage`: at least
    ``min_detections`` detections, the last within ``window_s`` s) and the latest
    confirmed tracks moved to the truth time with their velocity; plus counts, latency
    and the services' last Status."""
    stats, topics = ReadStats(), Counter()
    messages = _scenario_order(path, stats, topics)
    truth = TruthObserver(Coverage(window_s, min_detections), c=gospa_c)
    demo = _DemoObserver()
    result = run_offline(messages, None, OfflineConfig(tracker=None), [truth, demo])
    scores = truth.summary().get("truth", {})
    gospa = scores.get("gospa", {})
    summary = {
        "recording": str(path),
        "recording_truncated": stats.truncated,
        "recording_rejected": dict(stats.rejected),
        "messages_recorded": int(sum(topics.values())),
        "messages_by_topic": dict(sorted(topics.items())),
        "radars": sorted(result.sites),
        **demo.summary(),
        "targets_truth": scores.get("targets_truth", 0),
        "targets_detectable": scores.get("targets_detectable", 0),
        "targets_confirmed": scores.get("targets_confirmed", 0),
        "gospa_c_m": gospa_c,
        "gospa_mean_m": gospa.get("mean_m"),
        "gospa_mean_second_half_m": gospa.get("mean_second_half_m"),
        "gospa_final_m": gospa.get("final_m"),
        "gospa_final_missed": gospa.get("final_missed"),
        "gospa_final_false": gospa.get("final_false"),
        "truth": scores,
    }
    by_callsign = demo.tracks_by_callsign()
    if by_callsign:  # only when the tracks carry identities (the report is unchanged else)
        summary["tracks_by_callsign"] = by_callsign
    return DemoReport(
        summary, dict(demo.truth_tracks), demo.track_points(), list(result.sites.values())
    )


def identity_lines(summary: dict, limit: int = 20) -> list[str]:
    """The report's lines listing tracks by callsign (none without identities)."""
    by_callsign = summary.get("tracks_by_callsign") or {}
    if not by_callsign:
        return []
    items = list(by_callsign.items())
    text = ", ".join(f"{name} {'/'.join(map(str, ids))}" for name, ids in items[:limit])
    more = f" … (+{len(items) - limit})" if len(items) > limit else ""
    return [f"  tracks by callsign       : {text}{more}"]


def plot_tracks_vs_truth(ev: DemoReport, path: Path, title: str = "skyfuse demo") -> None:
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
