"""skyfuse tracker cost per scan and peak memory vs targets and clutter plots per scan.

Planar 2-D traffic (no frames: :class:`fusion.tracker.Tracker` directly): targets fly
straight at 200 m/s in a 200 km × 200 km area, one sensor with R = (25 m)² I,
P_D = 0.9, T = 1 s, uniform Poisson clutter with the given mean plots per scan. Every
target starts with an established track, so the figures are steady-state costs:
prediction, gating, association, components, management and two-point initiation from
all the plots no track took (clutter makes tentative tracks that live a few scans).

Two sweeps per tracker (``lmits`` N = 3 and ``gnn``): targets 10 … 2,000 at fixed
clutter, and clutter 0 … 10,000 at fixed targets; plus the target point (1,000 targets,
5,000 clutter plots). Peak memory is the tracemalloc peak of a separate, untimed pass
over the same scans (tracemalloc slows allocation; NumPy reports its buffers to it).
The largest case of each sweep is profiled (cProfile) and the time split by tracker
stage. A log–log fit of ms/scan against the swept variable over its upper half gives the
growth exponent (also over the last two points, and for clutter the exponent of the cost
above the no-clutter run, i.e. the part the clutter adds).

    python benchmarks/scaling.py                 # full grid, ~1 min (4 min on a loaded machine)
    python benchmarks/scaling.py --quick         # small grid, ~10 s

Writes ``benchmarks/results/scaling.json`` and ``docs/performance/scaling.png``.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import platform
import pstats
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig  # noqa: E402

SIDE = 200_000.0
SPEED = 200.0
SIGMA = 25.0
PD = 0.9
NS = 10**9

#: tracker stages: (label, function names whose cumulative time is the stage)
STAGES = [
    ("validate plots", ("validated",)),
    ("coverage + predict", ("select_tracks", "predict")),
    ("gating", ("gate",)),
    ("association", ("_associate",)),
    ("components (update, merge, prune)", ("its_update", "singer_merge", "prune")),
    ("moment match (output)", ("moment_match",)),
    ("management", ("duplicates", "shared_plot_pairs", "to_terminate", "to_confirm")),
    ("initiation", ("_initiate",)),
    ("output prediction", ("_predict_out",)),
]


def make_scans(n_targets: int, n_clutter: int, scans: int, seed: int = 0):
    """Initial target states and the plot batches of ``scans`` scans (prepared untimed)."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0.1 * SIDE, 0.9 * SIDE, (n_targets, 2))
    head = rng.uniform(0, 2 * np.pi, n_targets)
    vel = SPEED * np.column_stack([np.sin(head), np.cos(head)])
    x0 = np.column_stack([pos[:, 0], vel[:, 0], pos[:, 1], vel[:, 1]])
    rho = max(n_clutter / SIDE**2, 1e-12)
    batches = []
    for k in range(1, scans + 1):
        p = pos + vel * k
        det = rng.random(n_targets) < PD
        z = p[det] + rng.normal(0, SIGMA, (int(det.sum()), 2))
        c = rng.uniform(0, SIDE, (rng.poisson(n_clutter), 2))
        batches.append(
            MeasurementBatch(k * NS, "bench", np.vstack([z, c]), SIGMA**2 * np.eye(2), PD, rho)
        )
    return x0, batches


def new_tracker(kind: str, x0: np.ndarray, motion: str = "cv") -> Tracker:
    cfg = TrackerConfig(
        tracker=kind, depth=3, q=1.0, v_max=250.0, init_max_dt=1.5, psi_init=0.01,
        clutter="known", motion=motion,
    )  # fmt: skip
    tr = Tracker(cfg)
    P0 = np.diag([SIGMA**2, 100.0, SIGMA**2, 100.0])
    for x in x0:
        tr.add_track(x, P0, 0, existence=0.99, confirmed=True)
    return tr


def run_case(
    kind: str, n_targets: int, n_clutter: int, scans: int, warmup: int, motion: str = "cv"
) -> dict:
    x0, batches = make_scans(n_targets, n_clutter, warmup + scans)
    tr = new_tracker(kind, x0, motion)
    times, cpu, tracks, comps, pairs = [], [], [], [], []
    for k, b in enumerate(batches):
        t0, c0 = time.perf_counter(), time.process_time()
        out = tr.step(b)
        dt, dc = time.perf_counter() - t0, time.process_time() - c0
        if k >= warmup:
            times.append(dt * 1e3)
            cpu.append(dc * 1e3)
            tracks.append(len(out))
            comps.append(out.stats["components"])
            pairs.append(out.stats["gated_pairs"])
    # peak memory: a separate pass over the same scans (steady state after warm-up)
    tr = new_tracker(kind, x0, motion)
    for b in batches[:warmup]:
        tr.step(b)
    tracemalloc.start()
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    for b in batches[warmup : warmup + 3]:
        tr.step(b)
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    conf = out.confirmed
    est = out.states[conf][:, [0, 2]]
    truth = x0[:, [0, 2]] + x0[:, [1, 3]] * (warmup + scans)
    held = 0
    if len(est):
        # nearest confirmed track within 5 σ, via sorting on x (no n × m matrix)
        order = np.argsort(est[:, 0])
        xs = est[order, 0]
        lo = np.searchsorted(xs, truth[:, 0] - 5 * SIGMA)
        hi = np.searchsorted(xs, truth[:, 0] + 5 * SIGMA)
        for i in range(len(truth)):
            cand = est[order[lo[i] : hi[i]]]
            if len(cand) and np.min(np.hypot(*(cand - truth[i]).T)) < 5 * SIGMA:
                held += 1
    return {
        "tracker": kind,
        "motion": motion,
        "targets": n_targets,
        "clutter_per_scan": n_clutter,
        "ms_per_scan_median": round(float(np.median(times)), 2),
        "cpu_ms_per_scan_median": round(float(np.median(cpu)), 2),
        "ms_per_scan_mean": round(float(np.mean(times)), 2),
        "ms_per_scan_max": round(float(np.max(times)), 2),
        "peak_memory_mb": round(peak / 2**20, 2),
        "live_tracks_mean": round(float(np.mean(tracks)), 1),
        "components_mean": round(float(np.mean(comps)), 1),
        "gated_pairs_mean": round(float(np.mean(pairs)), 1),
        "targets_held": held,
    }


def profile_case(kind: str, n_targets: int, n_clutter: int, scans: int, warmup: int) -> dict:
    """Share of the step time per tracker stage (cProfile cumulative times)."""
    x0, batches = make_scans(n_targets, n_clutter, warmup + scans, seed=1)
    tr = new_tracker(kind, x0)
    for b in batches[:warmup]:
        tr.step(b)
    prof = cProfile.Profile()
    prof.enable()
    for b in batches[warmup:]:
        tr.step(b)
    prof.disable()
    st = pstats.Stats(prof).stats
    cum: dict[str, float] = {}
    total = 0.0
    for (fname, _line, func), (_cc, _nc, _tt, ct, _callers) in st.items():
        if "/fusion/" in fname.replace("\\", "/"):
            if func == "step" and fname.endswith("tracker.py"):
                total = ct
            cum[func] = cum.get(func, 0.0) + ct
    # moment_match inside singer_merge is counted under components; the output match
    # is the remainder
    shares = {}
    for label, funcs in STAGES:
        shares[label] = sum(cum.get(f, 0.0) for f in funcs)
    shares["moment match (output)"] = max(
        0.0, shares["moment match (output)"] - cum.get("singer_merge", 0.0)
    )
    shares["coverage + predict"] = cum.get("select_tracks", 0.0)  # predict also runs in others
    rest = total - sum(shares.values())
    out = {k: round(100 * v / total, 1) for k, v in shares.items()} if total else {}
    out["other (step body)"] = round(100 * rest / total, 1) if total else 0.0
    return {"tracker": kind, "targets": n_targets, "clutter_per_scan": n_clutter, "percent": out}


def fit_exponent(x: list[float], y: list[float]) -> float:
    """Slope of log y against log x (least squares)."""
    lx, ly = np.log(np.asarray(x, float)), np.log(np.asarray(y, float))
    return float(np.polyfit(lx, ly, 1)[0])


def plot(res: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, sweep, xkey, xlabel in (
        (axes[0], "targets_sweep", "targets", "targets"),
        (axes[1], "clutter_sweep", "clutter_per_scan", "clutter plots per scan"),
    ):
        for kind, marker in (("lmits", "o"), ("gnn", "s")):
            rows = [r for r in res[sweep] if r["tracker"] == kind and r[xkey] > 0]
            if not rows:
                continue
            x = [r[xkey] for r in rows]
            y = [r["ms_per_scan_median"] for r in rows]
            fit = res["exponents"].get(f"{kind}_{sweep}")
            lab = f"{kind}" + (f" (slope {fit:.2f} upper half)" if fit is not None else "")
            ax.loglog(x, y, marker=marker, label=lab)
        fixed = res["settings"]["clutter_fixed" if sweep == "targets_sweep" else "targets_fixed"]
        other = "clutter/scan" if sweep == "targets_sweep" else "targets"
        ax.set_title(f"ms per scan vs {xlabel} ({fixed} {other})")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("ms per scan (median)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def target_point(scans: int, warmup: int, show) -> list[dict]:
    """lmits at 1,000 targets + 5,000 clutter plots with CV and the two IMM densities
    (CPU time per scan relative to CV)."""
    r = run_case("lmits", 1000, 5000, scans, warmup)
    show(r)
    rows = [r]
    for motion in ("imm-cv-ct", "imm-cv-singer"):
        ri = run_case("lmits", 1000, 5000, scans, warmup, motion)
        ri["cpu_relative_to_cv"] = round(
            ri["cpu_ms_per_scan_median"] / r["cpu_ms_per_scan_median"], 2
        )
        rows.append(ri)
        show(ri)
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="small grid")
    ap.add_argument("--scans", type=int, default=6, help="timed scans per case")
    ap.add_argument("--warmup", type=int, default=3)
    ap.add_argument("--clutter-fixed", type=int, default=1000, help="clutter of the target sweep")
    ap.add_argument("--targets-fixed", type=int, default=1000, help="targets of the clutter sweep")
    ap.add_argument("--json", type=Path, default=ROOT / "benchmarks" / "results" / "scaling.json")
    ap.add_argument("--png", type=Path, default=ROOT / "docs" / "performance" / "scaling.png")
    ap.add_argument(
        "--point",
        action="store_true",
        help="only the target point (lmits, 1,000 targets + 5,000 clutter, cv and IMM): "
        "for before/after runs of two source trees (PYTHONPATH) side by side",
    )
    args = ap.parse_args(argv)
    if args.quick:
        targets, clutter = [10, 100, 300], [0, 300, 1000]
        args.targets_fixed, args.clutter_fixed = min(args.targets_fixed, 300), 300
    else:
        targets = [10, 30, 100, 300, 1000, 2000]
        clutter = [0, 100, 300, 1000, 3000, 10000]
    res: dict = {
        "benchmark": "scaling",
        "command": " ".join(["python", "benchmarks/scaling.py", *(argv or sys.argv[1:])]),
        "settings": {
            "area_m": SIDE,
            "speed_mps": SPEED,
            "sigma_m": SIGMA,
            "p_detection": PD,
            "scan_period_s": 1.0,
            "timed_scans": args.scans,
            "warmup_scans": args.warmup,
            "clutter_fixed": args.clutter_fixed,
            "targets_fixed": args.targets_fixed,
            "initiation": "two_point, v_max 250 m/s",
            "q": 1.0,
        },
        "machine": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "platform": platform.platform(),
            "load_average_1_5_15_min": [round(v, 2) for v in os.getloadavg()],
        },
        "targets_sweep": [],
        "clutter_sweep": [],
        "target_point": [],
        "profiles": [],
        "exponents": {},
    }
    hdr = f"{'tracker':>7} {'targets':>7} {'clutter':>7} {'ms/scan':>8} {'max':>7} {'MB':>7} "
    print(hdr + f"{'tracks':>7} {'comps':>7} {'pairs':>7} {'held':>5}", flush=True)

    def show(r: dict) -> None:
        print(
            f"{r['tracker'] + ('' if r['motion'] == 'cv' else '/' + r['motion']):>7} "
            f"{r['targets']:>7} {r['clutter_per_scan']:>7} "
            f"{r['ms_per_scan_median']:>8.1f} {r['ms_per_scan_max']:>7.1f} "
            f"{r['peak_memory_mb']:>7.1f} {r['live_tracks_mean']:>7.0f} "
            f"{r['components_mean']:>7.0f} {r['gated_pairs_mean']:>7.0f} {r['targets_held']:>5}",
            flush=True,
        )

    if args.point:
        res["target_point"] = target_point(args.scans, args.warmup, show)
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(res, indent=2) + "\n")
        print(f"wrote {args.json}")
        return 0
    for kind in ("lmits", "gnn"):
        for n in targets:
            r = run_case(kind, n, args.clutter_fixed, args.scans, args.warmup)
            res["targets_sweep"].append(r)
            show(r)
        for m in clutter:
            r = run_case(kind, args.targets_fixed, m, args.scans, args.warmup)
            res["clutter_sweep"].append(r)
            show(r)
        for sweep, xkey in (("targets_sweep", "targets"), ("clutter_sweep", "clutter_per_scan")):
            rows = [r for r in res[sweep] if r["tracker"] == kind and r[xkey] > 0]
            upper = rows[len(rows) // 2 :]
            if len(upper) >= 2:
                x = [r[xkey] for r in upper]
                y = [r["ms_per_scan_median"] for r in upper]
                res["exponents"][f"{kind}_{sweep}"] = round(fit_exponent(x, y), 2)
                res["exponents"][f"{kind}_{sweep}_last_segment"] = round(
                    fit_exponent(x[-2:], y[-2:]), 2
                )
        # the clutter-driven part alone: cost above the no-clutter run
        rows = [r for r in res["clutter_sweep"] if r["tracker"] == kind]
        base = [r["ms_per_scan_median"] for r in rows if r["clutter_per_scan"] == 0]
        inc = [
            (r["clutter_per_scan"], r["ms_per_scan_median"] - base[0])
            for r in rows
            if base and r["clutter_per_scan"] >= 1000 and r["ms_per_scan_median"] > base[0]
        ]
        if len(inc) >= 2:
            res["exponents"][f"{kind}_clutter_increment"] = round(
                fit_exponent([a for a, _ in inc], [b for _, b in inc]), 2
            )
    if not args.quick:
        res["target_point"] = target_point(args.scans, args.warmup, show)
    for kind in ("lmits", "gnn"):
        for n, m in ((max(targets), args.clutter_fixed), (args.targets_fixed, max(clutter))):
            p = profile_case(kind, n, m, args.scans, args.warmup)
            res["profiles"].append(p)
            top = sorted(p["percent"].items(), key=lambda kv: -kv[1])[:4]
            print(
                f"profile {kind} {n} targets {m} clutter: " + ", ".join(f"{k} {v}%" for k, v in top)
            )
    print("exponents (upper half of each sweep):", res["exponents"])
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(res, indent=2) + "\n")
    plot(res, args.png)
    print(f"wrote {args.json} and {args.png}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
