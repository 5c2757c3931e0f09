"""Particle track density (fusion.particles) speed, side by side with a Gaussian density.

Scenario (the [LM-IPF] scenario's geometry, generated here): n targets start on a circle
of r = 450 m around (500, 500) m, 10° apart on an arc, and fly straight through the
centre at 22.5 m/s; T = 1 s, R = (5 m)² I, P_D = 0.8, optional uniform Poisson clutter over the
[0, 1000]² m area (the source has none; a nominal ρ = 1e-6 m⁻² is used then). Every
target has an established track from scan 0, so the figures are steady-state per-scan
costs over the scans that follow (the converging targets share plots near the centre).

Three trackers see the same plots, timed one after another on every scan:

* **particle**: ``ParticleDensity`` with N particles per track — predict ([LM-IPF] eq. 6),
  gate + per-particle likelihood table (eq. 7-9), LM step and association (eq. 14-17),
  weight update + MMSE + systematic resampling of all tracks (eq. 11), existence (eq. 12);
* **gaussian**: the same tracks as Kalman (Gaussian) densities through the same gate and
  the same LM step (LM-IPDA): kalman predict, per-pair Kalman updates and a PDA moment
  match — the Gaussian density cost of the same work;
* **lmits**: the full ``fusion.tracker.Tracker`` with LM-ITS, N = 3 (the issue's
  reference: the particle trackers' target is ≤ 5× its CPU per scan). It also runs
  initiation and management, which the two density loops do not.

Ratios are medians over scans of the per-scan ratio. Throughput: particles·plots per
second = Σ(gated pairs) · N / time, for the likelihood table and for the update +
resample stage.

    python benchmarks/particles_speed.py            # 5 and 15 tracks, N = 1000, 40 scans
    python benchmarks/particles_speed.py --quick    # 10 scans

Writes ``benchmarks/results/particles_speed.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from scipy import stats  # noqa: E402
from skyfuse.fusion.association.gating import gate, gate_probability  # noqa: E402
from skyfuse.fusion.filters import kalman  # noqa: E402
from skyfuse.fusion.models import ConstantVelocity  # noqa: E402
from skyfuse.fusion.particles.association import lm_ipf_association  # noqa: E402
from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig  # noqa: E402
from skyfuse.fusion.tracker.components import moment_match  # noqa: E402
from skyfuse.fusion.tracker.density.particles import ParticleDensity, ParticleGatedTable  # noqa: E402
from skyfuse.fusion.tracker.store import NewTracks, store_for  # noqa: E402

SIGMA, PD, P11, Q_ACC, SPEED, NS = 5.0, 0.8, 0.98, 0.75, 22.5, 10**9
RHO_NOMINAL = 1e-6
P0 = np.diag([SIGMA**2, 4.0, SIGMA**2, 4.0])


def make_scans(n: int, scans: int, clutter: float, seed: int = 1):
    """Initial states (n, 4) and per-scan plots (z (m, 2)) of the [LM-IPF] scenario geometry."""
    rng = np.random.default_rng(seed)
    ang = np.deg2rad(180.0 + 10.0 * (np.arange(n) - (n - 1) / 2))
    start = 500.0 + 450.0 * np.column_stack([np.cos(ang), np.sin(ang)])
    vel = -SPEED * np.column_stack([np.cos(ang), np.sin(ang)])
    x0 = np.column_stack([start[:, 0], vel[:, 0], start[:, 1], vel[:, 1]])
    out = []
    for k in range(1, scans + 1):
        det = rng.random(n) < PD
        z = start[det] + vel[det] * k + rng.normal(0, SIGMA, (int(det.sum()), 2))
        c = rng.uniform(0, 1000.0, (rng.poisson(clutter * 1e6), 2))
        out.append(np.vstack([z, c]))
    return x0, out


class ParticleLoop:
    """LM-IPF over ParticleDensity for fixed tracks (existence kept, no management)."""

    def __init__(self, x0: np.ndarray, n_particles: int, g: float) -> None:
        self.density = ParticleDensity(ConstantVelocity(q=Q_ACC), n_particles, seed=0)
        store_for(self.density)
        self.density.tracks.append(NewTracks(x0, np.tile(P0, (len(x0), 1, 1))))
        self.psi = np.full(len(x0), 0.99)
        self.g, self.pdpg = g, np.full(len(x0), PD * gate_probability(g, 2))

    def step(self, z: np.ndarray, R: np.ndarray, rho: float) -> dict:
        t = [time.perf_counter()]
        rows = np.arange(len(self.psi))
        pred = self.density.predict(rows, np.ones(len(rows)))
        t.append(time.perf_counter())
        table = self.density.likelihoods(pred, z, R, self.g)
        t.append(time.perf_counter())
        psi_pred = P11 * self.psi
        res = lm_ipf_association(table, len(z), psi_pred, self.pdpg, np.full(len(table), rho))
        t.append(time.perf_counter())
        self.density.update(pred, table, res.beta0, res.beta)
        self.psi = res.psi_post
        t.append(time.perf_counter())
        names = ("predict", "likelihoods", "association", "update_resample")
        out = {k: t[i + 1] - t[i] for i, k in enumerate(names)}
        out["pairs"] = len(table)
        return out


class GaussianLoop:
    """LM-IPDA over Kalman densities of the same tracks, same gate and LM step."""

    def __init__(self, x0: np.ndarray, g: float) -> None:
        self.cv = ConstantVelocity(q=Q_ACC)
        self.x, self.P = x0.copy(), np.tile(P0, (len(x0), 1, 1))
        self.psi = np.full(len(x0), 0.99)
        self.g, self.pg = g, gate_probability(g, 2)
        self.pdpg = np.full(len(x0), PD * self.pg)

    def step(self, z: np.ndarray, R: np.ndarray, rho: float) -> None:
        n, H = len(self.x), self.cv.H()
        xp, Pp = kalman.predict(self.x, self.P, self.cv.F(1.0), self.cv.Q(1.0))
        pairs = gate(xp @ H.T, H @ Pp @ H.T, z, R, self.g)
        p = np.exp(pairs.log_pdf) / self.pg
        table = ParticleGatedTable(pairs.state, pairs.plot, p, np.zeros((len(p), 0)), pairs.d2, 1)
        res = lm_ipf_association(table, len(z), P11 * self.psi, self.pdpg, np.full(len(p), rho))
        xu, Pu, _, _ = kalman.update(
            xp[pairs.state], Pp[pairs.state], z[pairs.plot], H, R[pairs.plot]
        )
        w = np.concatenate([res.beta0, res.beta])
        group = np.concatenate([np.arange(n), pairs.state])
        _, self.x, self.P = moment_match(w, np.vstack([xp, xu]), np.vstack([Pp, Pu]), group, n)
        self.psi = res.psi_post


def lmits_tracker(x0: np.ndarray) -> Tracker:
    cfg = TrackerConfig(tracker="lmits", depth=3, q=Q_ACC, v_max=40.0, init_max_dt=1.5,
                        psi_init=0.01, clutter="known")  # fmt: skip
    tr = Tracker(cfg)
    for x in x0:
        tr.add_track(x, P0, 0, existence=0.99, confirmed=True)
    return tr


def timed(fn, *args) -> float:
    t0 = time.perf_counter()
    fn(*args)
    return time.perf_counter() - t0


def run_case(n: int, n_particles: int, scans: int, clutter: float, warmup: int = 3) -> dict:
    x0, plots = make_scans(n, warmup + scans, clutter)
    g = float(stats.chi2.ppf(0.99, 2))
    rho = max(clutter, RHO_NOMINAL)
    pf, gs, tr = ParticleLoop(x0, n_particles, g), GaussianLoop(x0, g), lmits_tracker(x0)
    rec: dict[str, list[float]] = {}
    for k, z in enumerate(plots):
        R = np.tile(SIGMA**2 * np.eye(2), (len(z), 1, 1))
        batch = MeasurementBatch((k + 1) * NS, "bench", z, SIGMA**2 * np.eye(2), PD, rho)
        stages = pf.step(z, R, rho)
        t_g = timed(gs.step, z, R, rho)
        t_l = timed(tr.step, batch)
        if k < warmup:
            continue
        stages["particle_scan"] = sum(v for s, v in stages.items() if s != "pairs")
        for key, v in {**stages, "gaussian_scan": t_g, "lmits_scan": t_l}.items():
            rec.setdefault(key, []).append(v)
    return summarise(n, n_particles, clutter, rec, pf)


def _ratio(rec: dict, reference: str) -> float:
    """Median over scans of the per-scan CPU ratio particle / reference (the two were timed
    back to back on the same scan, so slow phases of a shared machine cancel)."""
    r = np.asarray(rec["particle_scan"]) / np.asarray(rec[reference])
    return round(float(np.median(r)), 2)


def summarise(n: int, n_particles: int, clutter: float, rec: dict, pf: ParticleLoop) -> dict:
    ms = {k: float(np.median(v)) * 1e3 for k, v in rec.items() if k != "pairs"}
    pairs = np.asarray(rec["pairs"])
    work = pairs * n_particles
    lik_rate = work.sum() / np.sum(rec["likelihoods"])
    upd_rate = work.sum() / np.sum(rec["update_resample"])
    return {
        "tracks": n,
        "particles": n_particles,
        "clutter_per_m2": clutter,
        "gated_pairs_mean": round(float(pairs.mean()), 2),
        "ms_per_scan_median": {k: round(v, 3) for k, v in ms.items()},
        "particle_over_gaussian": _ratio(rec, "gaussian_scan"),
        "particle_over_lmits3": _ratio(rec, "lmits_scan"),
        "likelihood_particle_plots_per_s": float(f"{lik_rate:.3g}"),
        "update_particle_plots_per_s": float(f"{upd_rate:.3g}"),
        "final_existence_min": round(float(pf.psi.min()), 3),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scans", type=int, default=40)
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--quick", action="store_true", help="10 scans")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks/results/particles_speed.json")
    a = ap.parse_args(argv)
    scans = 10 if a.quick else a.scans
    load0 = os.getloadavg()
    cases = [run_case(n, a.particles, scans, clutter) for clutter in (0.0, 2e-5) for n in (5, 15)]
    for c in cases:
        m = c["ms_per_scan_median"]
        print(
            f"{c['tracks']:3d} tracks × {c['particles']} particles, clutter {c['clutter_per_m2']:g}"
            f"/m²: pairs {c['gated_pairs_mean']:5.1f}  particle {m['particle_scan']:.2f} ms"
            f" (lik {m['likelihoods']:.2f}, upd+res {m['update_resample']:.2f}, pred"
            f" {m['predict']:.2f})  gaussian {m['gaussian_scan']:.2f} ms  lmits3"
            f" {m['lmits_scan']:.2f} ms  ×gauss {c['particle_over_gaussian']}"
            f"  ×lmits {c['particle_over_lmits3']}  lik {c['likelihood_particle_plots_per_s']:.3g}"
            f" pp/s  upd {c['update_particle_plots_per_s']:.3g} pp/s"
        )
    result = {
        "benchmark": "particles_speed",
        "scans": scans,
        "loadavg_before": load0,
        "loadavg_after": os.getloadavg(),
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "cases": cases,
    }
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"load average {load0} → {os.getloadavg()}; wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
