"""Real Barcelona recording (15 min, one radar, Mode-S labels): plots near the radar and
the airborne / surface split of the label measures (docs/reports/registration-log.md §3-4).

Runs the recording through the same path as ``skyfuse eval FILE.ast --sites`` (ASTERIX
reader → ``TrackPipeline`` → ``PlotTrackRows``, default tracker configuration) and writes
one row per plot (time, Mode-S label, track, confirmed, altitude, slant range, valid)
to ``--rows`` (npz). It uses only APIs that existed before the near-radar work, so the same script
run against an older checkout gives the "before" rows. With ``--analyse A.npz [B.npz]``
it prints and writes (``--json``) the measures of
:func:`fusion.metrics.traffic_split.split_label_metrics` for each rows file.

    python benchmarks/near_radar_bcn.py --rows after.npz
    PYTHONPATH=<old checkout root> python benchmarks/near_radar_bcn.py --rows before.npz
    python benchmarks/near_radar_bcn.py --analyse before.npz after.npz --json out.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
RECORDING = DATA / "bcn_20230502_0800_0815_cat048.ast"
BCN_SITE = {"sac": 20, "sic": 129, "lat": 41.300702, "lon": 2.102058, "alt": 27.26}


def collect(path: Path, rows_out: Path, assumed: float = 3000.0, sigma: float = 3000.0) -> dict:
    """Track the recording (plots without a flight level at ``assumed`` ± ``sigma`` m, the
    evaluation's default 3000 ± 3000 m); save per-plot rows; return counts."""
    import tempfile

    from skyfuse.fusion.frames import SystemFrame, convert_plots
    from skyfuse.services.asterix import load_sites, read_asterix
    from skyfuse.services.evaluation.asterix import PlotTrackRows, rejection_reasons
    from skyfuse.services.fusion.pipeline import TrackPipeline

    with tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False) as f:
        f.write("[[radar]]\n" + "".join(f"{k} = {v}\n" for k, v in BCN_SITE.items()))
    sites = load_sites(f.name)
    t0 = time.perf_counter()
    res = read_asterix(path, sites=sites, sector_count=16)
    site = next(iter(res.sites.values()))
    frame = SystemFrame("stereographic", site.lat, site.lon, 0.0)
    pipe = TrackPipeline(frame, assumed_altitude=assumed)
    if sigma != 3000.0:  # the pipeline has no σ argument: wrap its conversion
        import skyfuse.services.fusion.pipeline as pl

        base = pl.convert_plots
        pl.convert_plots = lambda *a, **k: base(*a, **k, sigma_assumed_altitude=sigma)
    rows = PlotTrackRows()
    alt, rng, valid, near = [], [], [], 0
    for batch in res.batches:
        out = pipe.step(site, batch)
        rows.add(batch, out)
        if len(batch):
            a = batch.column("altitude")
            alt.append(np.full(len(batch), np.nan) if a is None else a)
            rng.append(batch.column("range"))
            v = np.zeros(len(batch), bool)
            v[np.asarray(out.batch.plot_ids)] = True
            valid.append(v)
            conv = convert_plots(frame, site, batch, assumed_altitude=assumed,
                                 sigma_assumed_altitude=sigma)  # fmt: skip
            near += int(getattr(conv, "n_near_radar", 0))
    t, label, track, conf = rows.arrays()
    np.savez(rows_out, time=t, label=label, track=track, confirmed=conf,
             altitude=np.concatenate(alt), range=np.concatenate(rng),
             valid=np.concatenate(valid))  # fmt: skip
    return {
        "plots": len(t),
        "rejected": rejection_reasons(pipe.rejected),
        "near_radar_plots": near,
        "assumed_altitude": [assumed, sigma],
        "wall_s": round(time.perf_counter() - t0, 1),
    }


def analyse(paths: list[Path]) -> dict:
    from skyfuse.fusion.metrics.traffic_split import split_label_metrics, traffic_class

    out = {}
    for p in paths:
        d = np.load(p)
        cls = traffic_class(d["altitude"], d["range"])
        m = split_label_metrics(d["time"], d["label"], d["track"], d["confirmed"], cls)
        m["plots_rejected"] = int((~d["valid"]).sum())
        out[p.stem] = m
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recording", type=Path, default=RECORDING)
    ap.add_argument("--rows", type=Path, help="track the recording, write rows here")
    ap.add_argument("--analyse", type=Path, nargs="+", help="rows files to score")
    ap.add_argument("--assumed-altitude", type=float, default=3000.0)
    ap.add_argument("--sigma-assumed-altitude", type=float, default=3000.0)
    ap.add_argument("--json", type=Path)
    a = ap.parse_args(argv)
    result = {}
    if a.rows:
        result["collect"] = collect(
            a.recording, a.rows, a.assumed_altitude, a.sigma_assumed_altitude
        )
        print(json.dumps(result["collect"], indent=1))
    if a.analyse:
        result["analysis"] = analyse(a.analyse)
        for name, m in result["analysis"].items():
            print(f"== {name}: plots rejected {m['plots_rejected']}")
            for cls in ("all", "airborne", "surface", "overhead"):
                print(f"  {cls:9s}", json.dumps(m[cls]))
    if a.json:
        a.json.write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
