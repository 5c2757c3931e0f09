"""Reproduction of the source's tracker experiments (spec 03 §3-§5, issue 6 §5).

Runs ``skyfuse eval`` on the thesis scenarios with ψ_init calibration and writes the
tables, curves and JSON to ``docs/reproduction/`` (the cache for resuming goes to
``out/reproduction-cache``, ignored by git). Experiments:

* ``stt``:   thesis-stt, IPDA vs ITS N = 1, 2, 3;
* ``mtt5``:  thesis-mtt-5, ITS vs LM-ITS, N = 1, 3, 5, 7, 9 (and 11);
* ``mtt15``: thesis-mtt-15, ITS vs LM-ITS, N = 1, 3, 5, 7, 9;
* ``mtt50``: thesis-mtt-50, ITS vs LM-ITS, N = 1, 3, 5, 7, 9.

    python benchmarks/reproduction.py                       # all, default run counts
    python benchmarks/reproduction.py mtt5 --runs 500 --calibration-runs 100
    nohup python benchmarks/reproduction.py --workers 1 > out/repro.log 2>&1 &

    python benchmarks/reproduction.py --delay   # confirmation-delay diagnostic only

Interrupted runs continue from the cache. ``docs/reproduction/timing.json`` records the
wall time of every experiment (calibration and runs) on this machine.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

from skyfuse.services.cli.main import main as skyfuse

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "reproduction"
CACHE = ROOT / "out" / "reproduction-cache"

EXPERIMENTS = {
    # name: (scenario, trackers, depths, default runs, default calibration runs)
    "stt": ("thesis-stt", "ipda,its", "1,2,3", 150, 30),
    "mtt5": ("thesis-mtt-5", "its,lmits", "1,3,5,7,9,11", 200, 50),
    "mtt15": ("thesis-mtt-15", "its,lmits", "1,3,5,7,9", 100, 20),
    "mtt50": ("thesis-mtt-50", "its,lmits", "1,3,5,7,9", 40, 10),
}


def confirmation_delay(runs: int = 15, seed: int = 7) -> dict:
    """Diagnostic of docs/reproduction.md "Why": first scan with a confirmed true track on
    target 0 of thesis-mtt-5 (ITS N = 1, no carry-over), per ψ_init, with the
    non-parametric clutter estimate and with a known density of 1e-6 m⁻²; 99 = never."""
    import numpy as np
    from skyfuse.fusion.evaluation import Experiment, Variant, VariantRunner

    out = {}
    for clutter, extra in (("estimated", {}), ("known", {"clutter_density_floor": 1e-6})):
        for psi in (0.01, 0.16, 0.5):
            firsts = []
            for r in range(runs):
                exp = Experiment(
                    scenario="thesis-mtt-5", trackers=["its"], depths=[1], runs=1,
                    seed=seed + r, tracker_settings={"clutter": clutter, **extra},
                    carry_false_tracks=False,
                )  # fmt: skip
                t = VariantRunner(exp, Variant("its", 1), psi).run(0).tracks
                ct = t.confirmed & (t.label == 0)
                firsts.append(int(t.scan[ct].min()) if ct.any() else 99)
            out[f"{clutter} psi_init={psi}"] = {
                "median": float(np.median(firsts)),
                "scans": sorted(firsts),
            }
            print(clutter, psi, out[f"{clutter} psi_init={psi}"], flush=True)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("experiments", nargs="*", default=[], help="stt, mtt5, mtt15, mtt50 (all)")
    ap.add_argument("--runs", type=int, default=None, help="Runs (default per experiment)")
    ap.add_argument("--calibration-runs", type=int, default=None)
    ap.add_argument("--no-calibrate", action="store_true", help="Use OUT/calibration-*.json")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--timing", type=Path, default=None, help="Default: OUT/timing.json")
    ap.add_argument("--delay", action="store_true", help="Only the confirmation-delay diagnostic")
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    if a.delay:
        (a.out / "confirmation-delay.json").write_text(json.dumps(confirmation_delay(), indent=1))
        return 0
    timing_path = a.timing or a.out / "timing.json"
    timing = json.loads(timing_path.read_text()) if timing_path.exists() else {}
    unknown = sorted(set(a.experiments) - set(EXPERIMENTS))
    if unknown:
        ap.error(f"experiment {unknown[0]!r}: choose from {', '.join(EXPERIMENTS)}")
    for name in a.experiments or list(EXPERIMENTS):
        scenario, trackers, depths, runs, cal_runs = EXPERIMENTS[name]
        runs = a.runs or runs
        cal_runs = a.calibration_runs or cal_runs
        argv = ["eval", scenario, "--trackers", trackers, "--depths", depths,
                "--runs", str(runs), "--seed", str(a.seed), "--workers", str(a.workers),
                "--out", str(a.out), "--cache", str(CACHE),
                "--calibration-file", str(a.out / f"calibration-{scenario}.json"),
                "--calibration-runs", str(cal_runs), "--no-progress"]  # fmt: skip
        if not a.no_calibrate:
            argv.append("--calibrate")
        print(f"== {name}: skyfuse {' '.join(argv)}", flush=True)
        t0 = time.perf_counter()
        code = skyfuse(argv)
        if code:
            return code
        summary = json.loads((a.out / f"{scenario}.json").read_text())
        timing[name] = {
            "scenario": scenario,
            "runs": runs,
            "calibration_runs": None if a.no_calibrate else cal_runs,
            "variants": len(summary["rows"]),
            "wall_s": round(time.perf_counter() - t0, 1),
            "calibration_s": summary.get("calibration_s"),
            "runs_s": summary.get("runs_s"),
            "workers": a.workers,
            "cpus": os.cpu_count(),
            "machine": platform.processor() or platform.machine(),
            "finished": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        }
        timing_path.write_text(json.dumps(timing, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
