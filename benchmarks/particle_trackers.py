"""CPU per scan of the particle trackers ``ipf`` / ``lmipf`` against ``lmits`` N = 3, through
the full ``fusion.tracker.Tracker`` (prediction, gating, LM step, association, update,
resampling, management, two-point initiation), side by side on the same plots.

Scenarios: the Monte Carlo evaluation's planar scenarios (``thesis-mtt-5``,
``thesis-mtt-15``, ``lm-ipf-15`` by default) with the evaluation's source settings
(``fusion.evaluation.Experiment.tracker_config``: q = 0.75, P_G = 0.99, estimated clutter,
two-point initiation from consecutive scans, v_max = 50 m/s, ψ_init = 0.01, false tracks
carried from run to run). Every scan's batch is given to each tracker in turn (the order
rotates from scan to scan), and each ``step`` is timed with the process CPU clock, so
machine load affects all trackers alike. Figures per tracker:

* ms per scan (mean), the ratio of total CPU to that of ``lmits`` N = 3, and the median of
  the per-scan ratios;
* for the particle trackers, particles·plots per second: Σ_scans (gated track × plot
  pairs) × N / CPU time of the whole step; the tracks and gated pairs per scan.

    python benchmarks/particle_trackers.py                     # 3 scenarios × 2 clutter, 5 runs
    python benchmarks/particle_trackers.py --runs 2 --scenarios thesis-mtt-5 --clutter 0

Clutter: the source scenarios have none (0); 2e-5 plots per m² per scan is 20 false plots
per scan over the 1000 × 1000 m area, which starts many tentative tracks (each with N
particles).

Writes ``benchmarks/results/particle_trackers.json``. Single-threaded BLAS (set before
NumPy is imported) so that the comparison does not depend on free cores.
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from skyfuse.fusion.evaluation import Experiment, Variant  # noqa: E402
from skyfuse.fusion.evaluation.runner import simulate_run  # noqa: E402
from skyfuse.fusion.tracker import MeasurementBatch, Tracker  # noqa: E402

VARIANTS = (Variant("lmits", 3), Variant("ipf", 0), Variant("lmipf", 0))
REFERENCE = "lmits"


def time_scenario(scenario: str, runs: int, particles: int, seed: int, clutter: float) -> dict:
    """Run ``runs`` consecutive Monte Carlo runs of ``scenario`` (with uniform Poisson
    clutter of ``clutter`` plots per m² per scan) through all trackers."""
    settings = {"particles": particles}
    params = {"clutter_density": clutter} if clutter > 0 else {}
    exp = Experiment(
        scenario=scenario, seed=seed, runs=runs, tracker_settings=settings, scenario_params=params
    )
    trackers = {v.tracker: Tracker(exp.tracker_config(v)) for v in VARIANTS}
    names = list(trackers)
    cpu = {n: [] for n in names}
    tracks = {n: [] for n in names}
    pairs = {n: [] for n in names}
    scan_no = 0
    for run in range(runs):
        d = simulate_run(exp, run)
        offset = round(run * d.duration * 1e9)
        R = d.sigma2 * np.eye(2)
        for j in range(len(d.scan)):
            batch = MeasurementBatch(
                time_ns=int(d.time_ns[j]) + offset,
                radar_id="sensor",
                z=d.z[j],
                R=R,
                p_detection=d.p_detection,
                clutter_density=0.0,
            )
            order = names[scan_no % len(names) :] + names[: scan_no % len(names)]
            scan_no += 1
            for n in order:
                t0 = time.process_time()
                out = trackers[n].step(batch)
                cpu[n].append(time.process_time() - t0)
                tracks[n].append(out.stats.get("tracks_in_coverage", 0))
                pairs[n].append(out.stats.get("gated_pairs", 0))
    return summarise(cpu, tracks, pairs, particles)


def summarise(cpu: dict, tracks: dict, pairs: dict, particles: int) -> dict:
    ref = np.asarray(cpu[REFERENCE])
    out = {}
    for n, c in cpu.items():
        c = np.asarray(c)
        row = {
            "scans": len(c),
            "cpu_s": float(c.sum()),
            "ms_per_scan": 1e3 * float(c.mean()),
            "ratio_total": float(c.sum() / ref.sum()),
            "ratio_median_per_scan": float(np.median(c / np.maximum(ref, 1e-9))),
            "tracks_per_scan": float(np.mean(tracks[n])),
            "gated_pairs_per_scan": float(np.mean(pairs[n])),
        }
        if n != REFERENCE:
            row["particles"] = particles
            row["particles_plots_per_s"] = float(np.sum(pairs[n]) * particles / c.sum())
        out[n] = row
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenarios", default="thesis-mtt-5,thesis-mtt-15,lm-ipf-15")
    ap.add_argument("--runs", type=int, default=5, help="consecutive Monte Carlo runs")
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--clutter", default="0,2e-5", help="clutter densities, plots per m² per scan (A,B,...)"
    )
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks/results/particle_trackers.json")
    a = ap.parse_args(argv)
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    results = {}
    cases = [(sc, float(c)) for sc in a.scenarios.split(",") for c in a.clutter.split(",")]
    for sc, clutter in cases:
        key = sc if clutter == 0 else f"{sc}@clutter={clutter:g}"
        results[key] = r = time_scenario(sc, a.runs, a.particles, a.seed, clutter)
        print(f"\n{key}: {a.runs} runs, N = {a.particles}")
        print(
            "| tracker | ms/scan | × lmits3 (total) | × lmits3 (median scan) | tracks | pairs "
            "| particles·plots/s |"
        )
        print("|---|---:|---:|---:|---:|---:|---:|")
        for n, row in r.items():
            pp = row.get("particles_plots_per_s")
            pps = f"{pp:.3g}" if pp else "–"
            print(
                f"| {n} | {row['ms_per_scan']:.2f} | {row['ratio_total']:.2f} | "
                f"{row['ratio_median_per_scan']:.2f} | {row['tracks_per_scan']:.1f} | "
                f"{row['gated_pairs_per_scan']:.1f} | {pps} |"
            )
    load1 = os.getloadavg()
    print(f"\nload average {load0[0]:.2f} before, {load1[0]:.2f} after; "
          f"{time.perf_counter() - t0:.1f} s")  # fmt: skip
    options = {k: getattr(a, k) for k in ("runs", "particles", "seed", "clutter")}
    machine = {"python": platform.python_version(), "numpy": np.__version__}
    machine["load_average_before_after"] = [load0[0], load1[0]]
    doc = {"benchmark": "particle_trackers", **options, **machine, "results": results}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(doc, indent=2) + "\n")
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
