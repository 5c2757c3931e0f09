"""Sector batches of a large regional simulation through ``TrackPipeline`` offline.

The live case (docs/performance.md): ≈1,000–4,000 tracks, 16 sector batches of 5–60 plots per
scan, several radars. The ``regional`` scenario (``--targets`` aircraft, ``--radars``
radars) is simulated once in this process; its sector batches (in time order, as the
fusion service's reorder buffer releases them) go through one ``TrackPipeline`` per
motion model (``--motions``, default ``cv`` and ``imm-cv-ct`` side by side in the same
run, alternating per repetition) with the service's defaults otherwise (LM-ITS N = 3,
registration on, publish confirmed). The first ``--warmup`` s of simulated time build up
the tracks and are not timed.

Per timed batch the stages are timed in CPU time of this process (``time.process_time``,
so that other jobs on a shared machine inflate the figures less than wall time would):
``convert`` (polar → system frame, ``TrackPipeline._convert``), ``track`` (``Tracker.step`` plus the
registration observation, ``TrackPipeline._track``), ``feed`` (``FeedBuilder.record`` +
``delta`` + ``to_json_bytes``: the delta message of the batch). Reported: plots/s over
the timed batches (plots / sum of the stages' CPU time), ms per batch by stage (mean and median),
tracks and plots per batch, load average before and after. JSON to ``--json``.

    python benchmarks/tracker_batches.py --targets 1000 --radars 4 --duration 120 \
        --json benchmarks/results/tracker_batches.json
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.fusion.tracker.config import TrackerConfig
from skyfuse.services.fusion.pipeline import TrackPipeline
from skyfuse.services.fusion.system_frame import frame_for_sites

STAGES = ("convert", "track", "feed")


def simulate(a) -> tuple[dict, list]:
    """Sites {radar id: RadarSite} and the sector batches in emission order."""
    sc = build_scenario(
        "regional", seed=a.seed, duration=a.duration, targets=a.targets, radars=a.radars
    )
    sites, batches = {}, []
    for ev in Simulator(sc, seed=a.seed).run(truth=False):
        if ev.kind == "site":
            sites[ev.message.radar_id] = ev.message
        elif ev.kind == "plots":
            batches.append(ev.message)
    return sites, batches


def run_motion(motion: str, sites: dict, batches: list, t_warm: int) -> dict:
    """One pass over the batches; stage times (s) of the batches after ``t_warm`` (ns)."""
    frame = frame_for_sites(sites.values())
    pipe = TrackPipeline(frame, TrackerConfig(motion=motion))
    times = {k: [] for k in STAGES}
    plots, tracks = [], []
    clock = time.process_time
    for b in batches:
        site = sites[b.radar_id]
        t0 = clock()
        conv = pipe._convert(site, b)
        t1 = clock()
        out = pipe._track(conv, site, b)
        t2 = clock()
        pipe.feed.record(out)
        msg = pipe.feed.delta(b.radar_id, b.seq)
        if msg is not None:
            msg.to_json_bytes()
        t3 = clock()
        if b.time_end >= t_warm:
            for k, v in zip(STAGES, (t1 - t0, t2 - t1, t3 - t2)):
                times[k].append(v)
            plots.append(len(b))
            tracks.append(len(out))
    total = sum(sum(v) for v in times.values())
    return {
        "motion": motion,
        "batches_timed": len(plots),
        "plots_timed": int(sum(plots)),
        "plots_per_s": sum(plots) / total if total else None,
        "ms_per_batch": {k: 1e3 * float(np.mean(v)) for k, v in times.items()},
        "ms_per_batch_median": {k: 1e3 * float(np.median(v)) for k, v in times.items()},
        "ms_per_batch_total": 1e3 * total / max(len(plots), 1),
        "plots_per_batch": {
            "mean": float(np.mean(plots)),
            "min": int(np.min(plots)),
            "max": int(np.max(plots)),
        },
        "tracks_per_batch": {"mean": float(np.mean(tracks)), "max": int(np.max(tracks))},
        "confirmed_at_end": int(out.confirmed.sum()),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--targets", type=int, default=1000)
    p.add_argument("--radars", type=int, default=4)
    p.add_argument("--duration", type=float, default=120.0, help="simulated s")
    p.add_argument("--warmup", type=float, default=40.0, help="simulated s not timed")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--motions", default="cv,imm-cv-ct")
    p.add_argument("--repeats", type=int, default=1)
    p.add_argument("--label", default="", help="free text stored in the JSON (e.g. commit)")
    p.add_argument("--json", type=Path, default=Path("benchmarks/results/tracker_batches.json"))
    a = p.parse_args()
    sites, batches = simulate(a)
    t_warm = int(batches[0].time_start + a.warmup * 1e9)
    load0 = os.getloadavg()
    runs = []
    motions = a.motions.split(",")
    for rep in range(a.repeats):
        order = motions if rep % 2 == 0 else motions[::-1]
        for motion in order:
            r = run_motion(motion, sites, batches, t_warm)
            r["repeat"] = rep
            runs.append(r)
            ms = ", ".join(f"{k} {v:.2f}" for k, v in r["ms_per_batch"].items())
            print(
                f"{motion:10s} rep {rep}: {r['plots_per_s']:8.0f} plots/s, "
                f"{r['ms_per_batch_total']:.2f} ms/batch ({ms}), "
                f"{r['plots_per_batch']['mean']:.1f} plots and "
                f"{r['tracks_per_batch']['mean']:.0f} tracks per batch"
            )
    load1 = os.getloadavg()
    print(f"load average {load0[0]:.2f} → {load1[0]:.2f}")
    result = {
        "label": a.label,
        "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(a).items()},
        "batches": len(batches),
        "plots": int(sum(len(b) for b in batches)),
        "load_average_start": load0,
        "load_average_end": load1,
        "runs": runs,
    }
    a.json.parent.mkdir(parents=True, exist_ok=True)
    a.json.write_text(json.dumps(result, indent=1))
    print(f"wrote {a.json}")


if __name__ == "__main__":
    main()
