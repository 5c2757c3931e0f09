"""Online registration on the regional scenario (docs/reports/registration-log.md §2).

Four radars (LYBE 3d 4 s, LYVR 2d 8 s, LRTR 2d 10 s, NOVISAD 3d 12 s), two of them
biased — LYVR and LRTR: azimuth +0.2°, range +150 m, time +50 ms — tracked at library
level (no Zenoh): ``fusion.sim`` → ``fusion.frames.convert_plots`` (with the estimator's
correction) → ``fusion.tracker.Tracker`` (default TrackerConfig) →
``fusion.registration.observe_tracker_output``. Reference radar: LYBE; NOVISAD is
estimated too (truth: zero bias). Runs, same seed and trajectories:

* ``unbiased`` — no biases, registration off (the target for the other two);
* ``biased_off`` — biases, registration off;
* ``biased_on`` — biases, registration on (default RegistrationConfig).

Reported per run, every ``--every`` s of simulated time: confirmed tracks per aircraft
(duplicates = confirmed tracks within ``--radius`` of a target beyond the one assigned),
position RMSE of the assigned tracks (Hungarian assignment on distance, gate
``--radius``), and for ``biased_on`` each radar's bias estimate ± σ against the truth.
Summaries over the second half of the run. JSON into benchmarks/results/registration.json;
``--plot DIR`` writes the figures used in docs/reports/registration-log.md.

    python benchmarks/registration.py [--duration 600] [--targets 40] [--seed 1]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from skyfuse.fusion.frames import SystemFrame, convert_plots  # noqa: E402
from skyfuse.fusion.registration import (  # noqa: E402
    RegistrationConfig,
    RegistrationEstimator,
    RegistrationMode,
    observe_tracker_output,
)
from skyfuse.fusion.sim import Simulator, build_scenario  # noqa: E402
from skyfuse.fusion.tracker import Tracker, TrackerConfig  # noqa: E402
from skyfuse.services.fusion.adapter import measurement_batch_from  # noqa: E402

BIASED = ("LYVR", "LRTR")
BIAS = {"bias_azimuth_deg": 0.2, "bias_range_m": 150.0, "bias_time_ms": 50.0}


def scenario(biased: bool, a):
    params = {f"{r}.{k}": v for r in BIASED for k, v in BIAS.items()} if biased else {}
    return build_scenario("regional", seed=a.seed, duration=a.duration, targets=a.targets,
                          **params)  # fmt: skip


def score(out, truth_xy, alive, radius):
    """(confirmed tracks near targets − assigned, assigned squared errors, targets with a
    track) at one instant."""
    conf = np.flatnonzero(out.confirmed)
    tgt = np.flatnonzero(alive)
    if not len(conf) or not len(tgt):
        return 0, np.zeros(0), 0
    xy = out.states[conf][:, [0, 2]]
    d = np.linalg.norm(xy[:, None, :] - truth_xy[None, tgt, :], axis=-1)
    r, c = linear_sum_assignment(np.where(d <= radius, d, 1e9))
    ok = d[r, c] <= radius
    near = (d <= radius).any(axis=1)
    return int(near.sum() - ok.sum()), d[r, c][ok] ** 2, int(ok.sum())


def run(name: str, biased: bool, mode: RegistrationMode, a) -> dict:
    sc = scenario(biased, a)
    sim = Simulator(sc)
    frame = SystemFrame.from_spec(sc.frame)
    sites = {s.radar_id: s for s in sc.sites}
    tracker = Tracker(TrackerConfig())
    est = RegistrationEstimator(RegistrationConfig(reference=["LYBE"], mode=mode))
    truth_bias = {b.radar_id: b for b in sim.radar_biases()}
    series, next_t, t_wall = [], a.every, time.perf_counter()
    for ev in sim.run(truth=False):
        if ev.kind != "plots":
            continue
        batch = ev.message
        corr = est.correction(batch.radar_id)
        conv = convert_plots(frame, sites[batch.radar_id], batch, bias=corr)
        mb = measurement_batch_from(conv, sites[batch.radar_id], batch)
        if corr is not None and corr.time_ns:
            # the sweep times are the radar's clock too: correct them like the plots
            cov = dataclasses.replace(mb.coverage, time_start=mb.coverage.time_start
                                      - corr.time_ns, time_end=mb.coverage.time_end
                                      - corr.time_ns)  # fmt: skip
            mb = dataclasses.replace(mb, time_ns=mb.time_ns - corr.time_ns, coverage=cov)
        out = tracker.step(mb)
        observe_tracker_output(est, out, conv, tracker.vel)
        t = (out.time_ns - sc.start_time) * 1e-9
        if t >= next_t:
            next_t += a.every
            tr = sim.truth_at(np.array([out.time_ns]), geodetic=False)
            xy = np.stack([tr["x"][0], tr["y"][0]], -1)
            dup, se, n_ok = score(out, xy, tr["alive"][0], a.radius)
            rec = {"t": round(t, 1), "duplicates": dup, "matched": n_ok,
                   "sq_err_sum": float(se.sum()), "targets": int(tr["alive"][0].sum())}  # fmt: skip
            if mode is RegistrationMode.ON:
                rec["estimates"] = [e.as_dict() for e in est.estimates()]
            series.append(rec)
    return summarise(name, series, truth_bias, est, time.perf_counter() - t_wall, a)


def summarise(name, series, truth_bias, est, wall, a) -> dict:
    late = [s for s in series if s["t"] >= a.duration / 2]
    n = sum(s["matched"] for s in late)
    out = {
        "run": name,
        "wall_s": round(wall, 1),
        "rmse_m": round(math.sqrt(sum(s["sq_err_sum"] for s in late) / max(n, 1)), 1),
        "duplicates_per_aircraft": round(sum(s["duplicates"] for s in late) / max(n, 1), 4),
        "matched_per_instant": round(n / max(len(late), 1), 2),
        "series": series,
    }
    if est.mode is RegistrationMode.ON:
        final = []
        for e in est.estimates():
            tb = truth_bias.get(e.radar_id)
            truth = tb and np.array([tb.azimuth, tb.range, tb.range_gain, tb.time])
            truth = np.zeros(4) if truth is None or truth is False else truth
            err = e.bias.vector() - truth
            z = np.where(e.sigma > 0, err / np.where(e.sigma > 0, e.sigma, 1), 0.0)
            rel = np.where(truth != 0, np.abs(err) / np.where(truth != 0, np.abs(truth), 1), 0)
            final.append({**e.as_dict(), "truth": truth.tolist(), "z": z.round(2).tolist(),
                          "relative_error": rel.round(3).tolist()})  # fmt: skip
        out["final_estimates"] = final
    return out


def _series(series, rid, key) -> np.ndarray:
    """One radar's estimate component over time (NaN before the radar was seen)."""
    return np.array([next((e[key] for e in s["estimates"] if e["radar_id"] == rid), np.nan)
                     for s in series])  # fmt: skip


def plot(results: dict, a, outdir: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    on = results["biased_on"]["series"]
    t = np.array([s["t"] for s in on])
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    labels = [("azimuth_deg", "azimuth_sigma_deg", "azimuth bias, deg", 0.2),
              ("range", "range_sigma", "range bias, m", 150.0),
              ("time", "time_sigma", "time bias, s", 0.05)]  # fmt: skip
    for ax, (key, sig, title, true) in zip(axes, labels):
        for rid in ("LYVR", "LRTR", "NOVISAD"):
            v, sd = _series(on, rid, key), _series(on, rid, sig)
            (ln,) = ax.plot(t, v, label=rid)
            ax.fill_between(t, v - 2 * sd, v + 2 * sd, color=ln.get_color(), alpha=0.15)
        ax.axhline(true, color="k", ls="--", lw=0.8)
        ax.axhline(0.0, color="grey", lw=0.5)
        ax.set_title(title)
        ax.set_xlabel("simulated time, s")
    axes[0].legend()
    fig.tight_layout()
    outdir.mkdir(parents=True, exist_ok=True)
    fig.savefig(outdir / "bias_convergence.png", dpi=90)
    fig, ax = plt.subplots(figsize=(6, 3.4))
    for name in ("unbiased", "biased_off", "biased_on"):
        s = results[name]["series"]
        ax.plot([x["t"] for x in s],
                [x["duplicates"] / max(x["matched"], 1) for x in s], label=name)  # fmt: skip
    ax.set_xlabel("simulated time, s")
    ax.set_ylabel("duplicate confirmed tracks / aircraft")
    ax.legend()
    fig.tight_layout()
    fig.savefig(outdir / "duplicates.png", dpi=90)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--targets", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--every", type=float, default=10.0)
    ap.add_argument("--radius", type=float, default=2000.0)
    ap.add_argument("--json", type=Path, default=ROOT / "benchmarks/results/registration.json")
    ap.add_argument("--plot", type=Path)
    ap.add_argument("--plot-only", action="store_true", help="figures from --json, no run")
    a = ap.parse_args(argv)
    if a.plot_only:
        plot(json.loads(a.json.read_text())["runs"], a, a.plot)
        return
    results = {}
    for name, biased, mode in (("unbiased", False, RegistrationMode.OFF),
                               ("biased_off", True, RegistrationMode.OFF),
                               ("biased_on", True, RegistrationMode.ON)):  # fmt: skip
        r = run(name, biased, mode, a)
        results[name] = r
        print(f"{name:11s} rmse {r['rmse_m']:7.1f} m  duplicates/aircraft "
              f"{r['duplicates_per_aircraft']:.3f}  matched {r['matched_per_instant']}  "
              f"wall {r['wall_s']} s", flush=True)  # fmt: skip
    for e in results["biased_on"]["final_estimates"]:
        print(f"  {e['radar_id']:8s} az {e['azimuth_deg']:+.4f}±{e['azimuth_sigma_deg']:.4f}° "
              f"range {e['range']:+7.1f}±{e['range_sigma']:.1f} m "
              f"gain {e['range_gain'] * 1e6:+6.1f}±{e['range_gain_sigma'] * 1e6:.1f} ppm "
              f"time {e['time'] * 1e3:+6.1f}±{e['time_sigma'] * 1e3:.1f} ms "
              f"z {e['z']}")  # fmt: skip
    with open("/proc/loadavg") as f:
        load = f.read().split()[:3]
    meta = {"duration_s": a.duration, "targets": a.targets, "seed": a.seed,
            "radius_m": a.radius, "every_s": a.every, "biased": list(BIASED), "bias": BIAS,
            "loadavg": load}  # fmt: skip
    a.json.parent.mkdir(parents=True, exist_ok=True)
    a.json.write_text(json.dumps({"meta": meta, "runs": results}, indent=1))
    if a.plot:
        plot(results, a, a.plot)


if __name__ == "__main__":
    main()
