"""Per-batch cost of the tracker at small and large sizes, with an optional profile.

Two kinds of cases (the Stone Soup comparison and the live service, docs/performance.md):

* ``small``: the plots of ``compare_stonesoup.py``'s ``manoeuvring`` (20 targets, 50
  false plots per scan, IMM ``gnn`` / ``jipda`` / ``lmits`` with ``imm-cv-ct``) and
  ``crossing`` (10 targets, 20 false plots per scan, ``lmits`` CV) cases, 60 scans, one
  cartesian sensor, through ``TrackPipeline.step`` (plot conversion included, as there);
* ``large``: the ``regional`` scenario (``--targets`` aircraft, 4 radars, 16 sector
  batches per 4 s revolution), its sector batches in time order through a
  ``TrackPipeline`` with the service defaults (LM-ITS N = 3; ``cv`` and ``imm-cv-ct``);
  after ``--warmup`` s of simulated time, ``Tracker.step`` alone is timed;
* ``--case SCENARIO:N:CLUTTER:KIND``: any other case of ``compare_stonesoup.py`` run like
  the small ones (e.g. ``manoeuvring:50:50:gnn:imm-cv-ct``, ``crossing:10:20:gnn``).

Times are CPU time of this process (``time.process_time``), mean ms per scan / batch,
median and minimum over ``--repeats`` passes (on a shared machine the minimum is the
pass least disturbed by other jobs). ``--profile`` adds a pyinstrument call tree (functions
above 2 % of the case) per case. To compare two source trees side by side, run the
script alternately with each tree's ``PYTHONPATH`` (docs/performance.md).

    python benchmarks/tracker_overhead.py --json benchmarks/results/tracker_overhead.json
    python benchmarks/tracker_overhead.py --cases large --profile
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from compare_stonesoup import build_setup, skyfuse_config
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.fusion.tracker.config import TrackerConfig
from skyfuse.services.fusion.pipeline import TrackPipeline
from skyfuse.services.fusion.system_frame import frame_for_sites

SMALL = [
    ("manoeuvring", 20, 50.0, "gnn:imm-cv-ct"),
    ("manoeuvring", 20, 50.0, "jipda:imm-cv-ct"),
    ("manoeuvring", 20, 50.0, "lmits:imm-cv-ct"),
    ("crossing", 10, 20.0, "lmits"),
]


def small_case(case: str, n: int, clutter: float, kind: str, scans: int):
    """A function running one pass (returns mean CPU ms per scan) and its label."""
    setup = build_setup(case, n, clutter, scans, 1)
    sim = Simulator(setup.scenario, seed=setup.scenario.seed)
    batches = []
    for k, scan in enumerate(sim.scans()):
        if k >= scans:
            break
        batches.append(Simulator.sector_batches(scan, k)[0])
    site = setup.scenario.sites[0]

    def run() -> float:
        pipe = TrackPipeline(setup.scenario.frame, skyfuse_config(setup, kind))
        total = 0.0
        for b in batches:
            t0 = time.process_time()
            pipe.step(site, b)
            total += time.process_time() - t0
        return 1e3 * total / len(batches)

    return run, f"{case} {n} targets {kind}"


def large_case(targets: int, motion: str, duration: float, warmup: float):
    """One pass over the regional sector batches after the warm-up (Tracker.step only)."""
    sc = build_scenario("regional", seed=1, duration=duration, targets=targets, radars=4)
    sites, batches = {}, []
    for ev in Simulator(sc, seed=1).run(truth=False):
        if ev.kind == "site":
            sites[ev.message.radar_id] = ev.message
        elif ev.kind == "plots":
            batches.append(ev.message)
    t_warm = int(batches[0].time_start + warmup * 1e9)
    frame = frame_for_sites(sites.values())

    def run() -> float:
        pipe = TrackPipeline(frame, TrackerConfig(motion=motion))
        step, timed = pipe.tracker.step, []

        def timed_step(mb):
            t0 = time.process_time()
            out = step(mb)
            timed.append(time.process_time() - t0)
            return out

        for b in batches:
            pipe.tracker.step = timed_step if b.time_end >= t_warm else step
            pipe.step(sites[b.radar_id], b)
        return 1e3 * float(np.mean(timed))

    return run, f"regional {targets} aircraft {motion} (Tracker.step per sector batch)"


def _parse_case(spec: str) -> tuple[str, int, float, str]:
    """``SCENARIO:N:CLUTTER:KIND`` (KIND may itself be ``TRACKER:MOTION``)."""
    scenario, n, clutter, kind = spec.split(":", 3)
    return scenario, int(n), float(clutter), kind


def profile(run, min_share: float = 0.02) -> str:
    from pyinstrument import Profiler

    p = Profiler(interval=0.0002)
    p.start()
    run()
    p.stop()
    text = p.output_text(unicode=False, color=False)
    total = p.last_session.duration
    keep = []
    for line in text.splitlines():
        parts = line.lstrip(" |`-").split(" ", 1)
        try:
            if float(parts[0]) >= min_share * total:
                keep.append(line)
        except ValueError:
            continue
    return "\n".join(keep)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", nargs="+", default=None, choices=["small", "large"],
                    help="default: small and large, none when --case is given")  # fmt: skip
    ap.add_argument(
        "--case",
        action="append",
        default=[],
        metavar="SCENARIO:N:CLUTTER:KIND",
        help="an extra small case of compare_stonesoup.py, e.g. manoeuvring:50:50:gnn:imm-cv-ct "
        "or crossing:10:20:gnn (repeatable; with only --case given, just these run)",
    )
    ap.add_argument("--scans", type=int, default=60, help="small cases: scans")
    ap.add_argument("--targets", type=int, default=1000, help="large case: aircraft")
    ap.add_argument("--duration", type=float, default=60.0, help="large case: simulated s")
    ap.add_argument("--warmup", type=float, default=30.0, help="large case: s not timed")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--profile", action="store_true", help="print a call tree per case")
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args(argv)
    cases = [small_case(*_parse_case(c), a.scans) for c in a.case]
    if a.cases is None:
        a.cases = [] if a.case else ["small", "large"]
    if "small" in a.cases:
        cases += [small_case(*c, a.scans) for c in SMALL]
    if "large" in a.cases:
        cases += [large_case(a.targets, m, a.duration, a.warmup) for m in ("cv", "imm-cv-ct")]
    load0, rows = os.getloadavg(), []
    for run, label in cases:
        runs = [run() for _ in range(a.repeats)]
        rows.append({"case": label, "cpu_ms": round(statistics.median(runs), 3),
                     "cpu_ms_min": round(min(runs), 3),
                     "cpu_ms_runs": [round(v, 3) for v in runs]})  # fmt: skip
        print(
            f"{label:<58} {rows[-1]['cpu_ms']:7.3f} ms, min {rows[-1]['cpu_ms_min']:.3f} "
            f"(runs {rows[-1]['cpu_ms_runs']})"
        )
        if a.profile:
            rows[-1]["profile"] = profile(run)
            print(rows[-1]["profile"])
    res = {
        "command": " ".join(["python", "benchmarks/tracker_overhead.py", *sys.argv[1:]]),
        "load_average_start": load0,
        "load_average_end": os.getloadavg(),
        "cases": rows,
    }
    print(f"load average {load0[0]:.2f} -> {res['load_average_end'][0]:.2f}")
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps(res, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
