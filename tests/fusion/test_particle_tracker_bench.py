"""benchmarks/particle_trackers.py runs end to end on one short run and writes its JSON
(no timing is asserted: only that every tracker stepped every scan, the particle trackers
gated plots, and the throughput figure follows from its definition)."""

from __future__ import annotations

import json
import runpy
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_particle_trackers_benchmark_writes_json(tmp_path):
    main = runpy.run_path(str(ROOT / "benchmarks" / "particle_trackers.py"))["main"]
    out = tmp_path / "pt.json"
    args = ["--runs", "1", "--scenarios", "thesis-mtt-5", "--clutter", "0", "--particles", "100"]
    args += ["--out", str(out)]
    assert main(args) == 0
    res = json.loads(out.read_text())["results"]["thesis-mtt-5"]
    assert set(res) == {"lmits", "ipf", "lmipf"}
    assert len({r["scans"] for r in res.values()}) == 1 and res["ipf"]["scans"] >= 20
    assert res["lmits"]["ratio_total"] == 1.0
    for kind in ("ipf", "lmipf"):
        r = res[kind]
        assert r["gated_pairs_per_scan"] > 1.0 and r["tracks_per_scan"] > 1.0
        expected = r["gated_pairs_per_scan"] * r["scans"] * 100 / r["cpu_s"]
        assert abs(r["particles_plots_per_s"] / expected - 1.0) < 1e-9
