"""Tracker cost per scan vs number of targets and clutter plots per scan.

Planar 2-D scenario (no frames, no simulator): targets fly straight at 200 m/s in a
200 km × 200 km area, one sensor with R = (25 m)² I, P_D = 0.9, scan period T = 1 s, and
uniform Poisson clutter with the given mean number of plots per scan. Every target starts
with an established track (so the figures are steady-state costs: prediction, gating,
association, components, management and two-point initiation from the clutter).

    python benchmarks/tracker_scaling.py            # full grid, ~2-4 min on 2 cores
    python benchmarks/tracker_scaling.py --quick    # small grid

Prints a table and writes ``benchmarks/results/tracker_scaling.json``.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from fusion.tracker import MeasurementBatch, Tracker, TrackerConfig

SIDE = 200_000.0
SPEED = 200.0
SIGMA = 25.0
PD = 0.9
NS = 10**9


def run_case(
    kind: str, depth: int, n_targets: int, n_clutter: int, scans: int, warmup: int, seed: int = 0
) -> dict:
    rng = np.random.default_rng(seed)
    cfg = TrackerConfig(
        tracker=kind,
        depth=depth,
        q=1.0,
        v_max=250.0,
        init_max_dt=1.5,
        psi_init=0.01,
        clutter="known",
    )
    tr = Tracker(cfg)
    pos = rng.uniform(0.1 * SIDE, 0.9 * SIDE, (n_targets, 2))
    head = rng.uniform(0, 2 * np.pi, n_targets)
    vel = SPEED * np.column_stack([np.sin(head), np.cos(head)])
    P0 = np.diag([SIGMA**2, 100.0, SIGMA**2, 100.0])
    for p, v in zip(pos, vel):
        tr.add_track([p[0], v[0], p[1], v[1]], P0, 0, existence=0.99, confirmed=True)
    rho = n_clutter / SIDE**2
    times, tracks, comps = [], [], []
    for k in range(1, warmup + scans + 1):
        pos = pos + vel
        det = rng.random(n_targets) < PD
        z = pos[det] + rng.normal(0, SIGMA, (int(det.sum()), 2))
        c = rng.uniform(0, SIDE, (rng.poisson(n_clutter), 2))
        batch = MeasurementBatch(
            k * NS, "bench", np.vstack([z, c]), SIGMA**2 * np.eye(2), PD, max(rho, 1e-12)
        )
        t0 = time.perf_counter()
        out = tr.step(batch)
        dt = time.perf_counter() - t0
        if k > warmup:
            times.append(dt * 1e3)
            tracks.append(len(out))
            comps.append(out.stats["components"])
    conf = out.confirmed
    est = out.states[conf][:, [0, 2]]
    d = np.min(np.linalg.norm(est[:, None, :] - pos[None], axis=2), axis=0) if len(est) else []
    return {
        "tracker": kind,
        "depth": depth,
        "targets": n_targets,
        "clutter_per_scan": n_clutter,
        "ms_per_scan_mean": round(float(np.mean(times)), 2),
        "ms_per_scan_median": round(float(np.median(times)), 2),
        "ms_per_scan_max": round(float(np.max(times)), 2),
        "live_tracks_mean": round(float(np.mean(tracks)), 1),
        "components_mean": round(float(np.mean(comps)), 1),
        "targets_held": int(np.sum(np.asarray(d) < 5 * SIGMA)) if len(d) else 0,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="small grid")
    ap.add_argument("--scans", type=int, default=6, help="timed scans per case")
    ap.add_argument(
        "--out", type=Path, default=Path(__file__).parent / "results" / "tracker_scaling.json"
    )
    args = ap.parse_args()
    targets = [10, 100] if args.quick else [10, 100, 300, 1000]
    clutter = [0, 500] if args.quick else [0, 500, 2000, 5000]
    cases = []
    print(
        f"{'tracker':>8} {'N':>2} {'targets':>7} {'clutter':>7} {'ms/scan':>8} "
        f"{'max':>7} {'tracks':>7} {'comps':>7} {'held':>5}"
    )
    for kind, depth in (("ipda", 0), ("lmits", 3)):
        for n in targets:
            for m in clutter:
                r = run_case(kind, depth, n, m, args.scans, warmup=3)
                cases.append(r)
                print(
                    f"{kind:>8} {depth:>2} {n:>7} {m:>7} {r['ms_per_scan_mean']:>8.1f} "
                    f"{r['ms_per_scan_max']:>7.1f} {r['live_tracks_mean']:>7.0f} "
                    f"{r['components_mean']:>7.0f} {r['targets_held']:>5}",
                    flush=True,
                )
    res = {
        "benchmark": "tracker_scaling",
        "setup": {
            "area_m": SIDE,
            "speed_mps": SPEED,
            "sigma_m": SIGMA,
            "p_detection": PD,
            "scan_period_s": 1.0,
            "timed_scans": args.scans,
            "warmup_scans": 3,
            "initiation": "two_point, v_max 250 m/s",
        },
        "machine": {
            "python": platform.python_version(),
            "processor": platform.processor(),
            "numpy": np.__version__,
        },
        "cases": cases,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(res, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
