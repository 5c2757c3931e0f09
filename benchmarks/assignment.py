"""Auction (pure-Python bidding loop over NumPy rows, ε-scaling) vs scipy's
Jonker-Volgenant ``linear_sum_assignment`` on GNN-like problems: n tracks, n plots,
each track gating a few nearby plots (sparse costs d² + ln det S), miss cost at the gate
edge. Prints a table and writes JSON.

    python benchmarks/assignment.py [--json benchmarks/assignment.json] [--repeats 20]
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np
from skyfuse.fusion.association import assign_auction, assign_jv


def gnn_like_problem(n: int, rng: np.random.Generator, density: float = 3.0):
    """n tracks and n plots on a line of targets; each track sees ≈ density plots."""
    pos = np.sort(rng.uniform(0, n, n))
    plots = pos + rng.normal(0, 0.3, n)
    d2 = ((plots[None, :] - pos[:, None]) / 0.3) ** 2 * (3.0 / density) ** 2
    cost = np.where(d2 <= 16.2, d2 + 10.0, np.inf)
    miss = np.full(n, 16.2 + 10.0)
    return cost, miss


def bench(n: int, repeats: int, rng) -> dict:
    t_auc, t_jv, gaps = [], [], []
    for _ in range(repeats):
        cost, miss = gnn_like_problem(n, rng)
        t0 = time.perf_counter()
        a = assign_auction(cost, miss)
        t1 = time.perf_counter()
        j = assign_jv(cost, miss)
        t2 = time.perf_counter()
        t_auc.append(t1 - t0)
        t_jv.append(t2 - t1)
        gaps.append(abs(a.total_cost - j.total_cost))
    return {
        "n_tracks": n,
        "n_plots": n,
        "auction_ms_median": 1e3 * float(np.median(t_auc)),
        "jv_ms_median": 1e3 * float(np.median(t_jv)),
        "max_cost_gap": float(max(gaps)),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default=None, help="write results to this JSON file")
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--sizes", default="2,5,10,20,50,100,200")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    rows = [bench(int(n), args.repeats, rng) for n in args.sizes.split(",")]
    print(f"{'n':>5} {'auction ms':>11} {'JV ms':>9} {'ratio':>7} {'max |Δcost|':>12}")
    for r in rows:
        print(
            f"{r['n_tracks']:>5} {r['auction_ms_median']:>11.3f} {r['jv_ms_median']:>9.3f} "
            f"{r['auction_ms_median'] / r['jv_ms_median']:>7.1f} {r['max_cost_gap']:>12.2e}"
        )
    if args.json:
        out = {"machine": platform.platform(), "python": platform.python_version(), "rows": rows}
        with open(args.json, "w") as f:
            json.dump(out, f, indent=2)
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
