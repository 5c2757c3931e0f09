"""benchmarks/particles_speed.py runs end to end on a few scans and writes its JSON (no
timing is asserted: only that every case ran all three trackers and the particle loop
kept its tracks' existence meaningful)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_particles_speed_benchmark_writes_json(tmp_path):
    spec = importlib.util.spec_from_file_location(
        "particles_speed_bench", ROOT / "benchmarks" / "particles_speed.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = tmp_path / "ps.json"
    assert mod.main(["--scans", "4", "--particles", "200", "--out", str(out)]) == 0
    res = json.loads(out.read_text())
    assert [(c["tracks"], c["clutter_per_m2"]) for c in res["cases"]] == [
        (5, 0.0),
        (15, 0.0),
        (5, 2e-5),
        (15, 2e-5),
    ]
    for c in res["cases"]:
        ms = c["ms_per_scan_median"]
        assert {"particle_scan", "gaussian_scan", "lmits_scan", "likelihoods"} <= set(ms)
        assert c["gated_pairs_mean"] >= 0.5 * c["tracks"]  # P_D = 0.8, tracks on targets
        assert c["likelihood_particle_plots_per_s"] > 0
