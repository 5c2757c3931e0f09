"""Cost of the out-of-sequence update (fusion/tracker/oosm.py) per batch, side by side.

Planar 2-D traffic (:class:`fusion.tracker.Tracker` directly): ``--targets`` targets fly
straight at 200 m/s in a 200 km square, each with an established track; radar A sees
them all every 1 s (R = (50 m)² I, P_D = 0.9, ``--clutter`` uniform clutter plots), radar
B the same at t + 0.5 s, delivered *after* A's batch at t + 1 s (0.5 s late, so every
track of B's batch takes the OOSM pass). Three trackers step through identical batches
in turn, per batch kind, and the process time of each step is taken:

* ``oosm``: the default (OOSM on): A's batches carry the cost of recording the last
  step (moment match of the prior per track and mode), B's batches the OOSM pass;
* ``off``: ``oosm = False`` (B's plots applied at the tracks' newer time, as before);
* ``drop``: B's batches not applied (A's only); ``drop_off`` the same with OOSM off:
  the A-batch difference ``drop`` − ``drop_off`` is the cost of recording the last step.

Prints the median ms per A batch and per B batch and the RMS position error of the
confirmed tracks against the truth after each B batch, and writes
``benchmarks/results/oosm_cost.json``.

    python benchmarks/oosm_cost.py                      # 1,000 targets, lmits cv and IMM
    python benchmarks/oosm_cost.py --targets 200 --scans 8
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig

ROOT = Path(__file__).resolve().parents[1]
NS = 10**9
SIGMA = 50.0


def _scenario(n: int, seed: int):
    rng = np.random.default_rng(seed)
    p0 = rng.uniform(0, 200e3, (n, 2))
    head = rng.uniform(0, 2 * np.pi, n)
    v = 200.0 * np.column_stack([np.cos(head), np.sin(head)])
    return rng, p0, v


def _plots(rng, p0, v, t: float, clutter: int) -> np.ndarray:
    seen = rng.random(len(p0)) < 0.9
    z = (p0 + v * t)[seen] + rng.normal(0, SIGMA, (int(seen.sum()), 2))
    return np.concatenate([z, rng.uniform(0, 200e3, (clutter, 2))])


def _trackers(n, p0, v, motion):
    out = {}
    for name, oosm in (("oosm", True), ("off", False), ("drop", True), ("drop_off", False)):
        cfg = TrackerConfig(tracker="lmits", motion=motion, oosm=oosm, q=1.0, clutter="known")
        tr = Tracker(cfg)
        x = np.column_stack([p0[:, 0], v[:, 0], p0[:, 1], v[:, 1]])
        P = np.diag([SIGMA**2, 10.0**2, SIGMA**2, 10.0**2])
        for i in range(n):
            tr.add_track(x[i], P, 0, existence=0.99, confirmed=True)
        out[name] = tr
    return out


def _step(tr, t, radar, z, rho):
    c0 = time.process_time()
    out = tr.step(MeasurementBatch(round(t * NS), radar, z, SIGMA**2 * np.eye(2), 0.9, rho))
    return (time.process_time() - c0) * 1e3, out


def _rms(out, p0, v) -> float:
    c = np.flatnonzero(out.confirmed)
    if not len(c):
        return float("nan")
    x = out.states[c][:, [0, 2]]
    truth = p0 + v * out.time_ns / NS
    d = np.linalg.norm(x[:, None, :] - truth[None], axis=2).min(axis=1)
    return float(np.sqrt(np.mean(np.minimum(d, 1e3) ** 2)))


def run(n: int, clutter: int, scans: int, motion: str, seed: int = 1) -> dict:
    rng, p0, v = _scenario(n, seed)
    trackers = _trackers(n, p0, v, motion)
    rho = clutter / 200e3**2
    ms = {k: {"A": [], "B": []} for k in trackers}
    err = {k: [] for k in trackers}
    late, outs = None, {}
    for k in range(1, scans + 1):
        za = _plots(rng, p0, v, float(k), clutter)
        for name, tr in trackers.items():
            dt, outs[name] = _step(tr, float(k), "A", za, rho)
            ms[name]["A"].append(dt)
        if late is not None:  # B's batch of k − 0.5 arrives after A's of k
            for name, tr in trackers.items():
                if not name.startswith("drop"):
                    dt, outs[name] = _step(tr, late[0], "B", late[1], rho)
                    ms[name]["B"].append(dt)
                err[name].append(_rms(outs[name], p0, v))
        late = (k + 0.5, _plots(rng, p0, v, k + 0.5, clutter))
    return {
        name: {
            "ms_A": float(np.median(ms[name]["A"][2:])),
            "ms_B": float(np.median(ms[name]["B"][2:])) if ms[name]["B"] else None,
            "rms_m": float(np.nanmean(err[name][2:])),
        }
        for name in trackers
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--targets", type=int, default=1000)
    ap.add_argument("--clutter", type=int, default=1000, help="clutter plots per batch")
    ap.add_argument("--scans", type=int, default=10)
    ap.add_argument("--json", type=Path, default=ROOT / "benchmarks" / "results" / "oosm_cost.json")
    a = ap.parse_args()
    result = {"targets": a.targets, "clutter": a.clutter, "scans": a.scans}
    result["loadavg"] = os.getloadavg()[0]
    for motion in ("cv", "imm-cv-ct"):
        r = run(a.targets, a.clutter, a.scans, motion)
        result[motion] = r
        for name, v in r.items():
            b = "—" if v["ms_B"] is None else f"{v['ms_B']:.1f}"
            ms_a, rms = v["ms_A"], v["rms_m"]
            print(f"{motion:10s} {name:5s} A {ms_a:7.1f} ms  B {b:>7s} ms  RMS {rms:.1f} m")
    result["loadavg_end"] = os.getloadavg()[0]
    print(f"load average {result['loadavg']:.1f} → {result['loadavg_end']:.1f}")
    a.json.parent.mkdir(parents=True, exist_ok=True)
    a.json.write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
