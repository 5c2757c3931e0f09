"""crossing-4g ([MZD] §2, §4): two targets crossing with opposite 4 g turns, one 2-D
radar, σ_r = 20 m, σ_θ 2.5 or 6 mrad, GNN association with the filters compared in the
source (PCWPA KF, Singer KF, two-model IMM), plus the IMM with p22 = 0.9 and [Dikić]'s
three-model CV/Singer/CT IMM; and any tracker of :mod:`fusion.tracker` with any motion
density, named ``KIND:MOTION`` (e.g. ``jipda:imm-cv-ct``, ``ipda:cv``). Position RMSE per
scan per filter, runs in which the two tracks swap or are lost. Every filter sees the same
simulated plots in a run (seed + run index).

Every filter runs in :class:`fusion.tracker.Tracker`. The source's filters (the baseline,
:func:`baseline_settings`) are the ``gnn`` kind with the classical life cycle
(``life_cycle = "m_of_n"``: a one-point tentative track from every unassigned plot,
confirmed with plots in 2 of its first 3 scans, deleted after 3 consecutive misses; [MZD]
§1 deletes tracks without new plots within a time window, the counts are [IMPL]) and the
motions ``cv`` (q = σ²), ``singer``, ``imm-pcwpa`` and ``imm-cv-singer-ct``
(:mod:`fusion.tracker.density.source_motions`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, Field, field_validator

G0 = 9.80665
TURN_START_S, TURN_END_S = 34.0, 42.0  # crossing-4g defaults ([MZD] §2), for the windows

FILTER_HELP = {
    "kf": "PCWPA (CV) KF, σ = --kf-sigma",
    "singer": "Singer KF (τ, A_max, P_max, P_0)",
    "imm2": "two-model PCWPA IMM, σ = g/2 and 2g, the source's printed TPM (p22 = 0.1)",
    "imm2-p22": "the same IMM with p22 = 0.9",
    "imm3": "three-model IMM: CV + Singer + coordinated turn ([Dikić])",
}


def filter_description(name: str) -> str:
    """Help text of a filter name: a GNN-baseline filter or ``KIND:MOTION``."""
    if name in FILTER_HELP:
        return FILTER_HELP[name]
    from skyfuse.fusion.tracker.registry import MOTIONS, TRACKERS

    kind, _, motion = name.partition(":")
    if kind in TRACKERS and motion in MOTIONS:
        return f"{TRACKERS[kind].description} tracker, {MOTIONS[motion].description}"
    raise ValueError(
        f"filter {name!r} is not known; choose from {', '.join(FILTER_HELP)} or KIND:MOTION "
        f"with KIND in {', '.join(TRACKERS)} and MOTION in {', '.join(MOTIONS)}"
    )


class CrossingEvalConfig(BaseModel):
    """Options of ``skyfuse eval crossing-4g``."""

    scenario: str = Field(description="Scenario to evaluate (supported: crossing-4g)")
    filters: list[str] = Field(
        ["kf", "singer", "imm2"],
        description="Filters: " + ", ".join(FILTER_HELP) + ", or an existence tracker "
        "KIND:MOTION (e.g. jipda:imm-cv-ct)",
    )
    runs: int = Field(300, ge=1, le=100_000, description="Monte Carlo runs")
    sigma_az_mrad: float = Field(2.5, gt=0, le=100, description="Azimuth noise σ_θ, mrad")
    seed: int = Field(1, ge=0, description="Seed; run r uses seed·100003 + r")
    out: Path | None = Field(None, description="Directory for the table and PNG figures")
    workers: int = Field(1, ge=1, le=64, description="Worker processes")
    p_gate: float = Field(0.9997, gt=0, lt=1, description="Gate probability P_G")
    imm_gating: Literal["mixed", "per-mode"] = Field(
        "per-mode",
        description="IMM gating of the baseline filters: any mode's gate ([MZD] §5) or the "
        "mode-mixed prediction's",
    )
    kf_sigma: float = Field(
        G0, gt=0, description="PCWPA KF acceleration σ, m/s² (source: not given; g)"
    )
    singer_tau: float = Field(10.0, gt=0, description="Singer manoeuvre time constant τ, s")
    singer_a_max: float = Field(40.0, gt=0, description="Singer A_max, m/s²")
    singer_p_max: float = Field(0.9, ge=0, le=1, description="Singer P_max (as printed in 003)")
    singer_p_0: float = Field(0.1, ge=0, le=1, description="Singer P_0 (as printed in 003)")
    tracker_config: Path | None = Field(
        None,
        description="TOML with a [tracker] table (TrackerConfig fields) for the KIND:MOTION "
        "filters; p_gate is always --p-gate",
    )
    first_scan: int = Field(2, ge=1, description="Scan at which tracks are matched to targets")
    follow_distance: float = Field(
        2000.0, gt=0, description="A track follows a target at the end if within this, m"
    )

    @field_validator("filters")
    @classmethod
    def _known_filters(cls, v: list[str]) -> list[str]:
        for name in v:
            filter_description(name)
        if not v:
            raise ValueError("give at least one filter")
        return v


# --------------------------------------------------------------------------------------
# crossing-4g: the computation (no I/O)
# --------------------------------------------------------------------------------------
SIGMA_V = 350.0
"""σ of the zero velocity of a one-point tentative track, m/s ([IMPL]): the tracker's
one-point initiation gives σ_v = v_max/√3, so the baseline runs with v_max = σ_v √3."""
IMM3_TPM = (0.90, 0.05, 0.05, 0.05, 0.90, 0.05, 0.05, 0.05, 0.90)
"""Transition matrix of the three-model IMM per scan (row-major; [IMPL], the source gives
none)."""


def baseline_settings(name: str, cfg: CrossingEvalConfig, scan_period: float) -> dict:
    """TrackerConfig settings of a baseline filter (``kf``, ``singer``, ``imm2``,
    ``imm2-p22``, ``imm3``): GNN, the classical life cycle, one-point initiation from the
    plots no track takes, the filter's motion and parameters (module docstring); the IMM
    transition matrices are per scan (``scan_period`` s)."""
    from skyfuse.fusion.models import Singer
    from skyfuse.fusion.tracker.density.source_motions import SOURCE_TPM_IMM2, TYPICAL_TPM_IMM2

    common = {
        "tracker": "gnn", "life_cycle": "m_of_n", "confirm_m_of_n": [2, 3], "max_misses": 3,
        "initiation": "one_point", "v_max": SIGMA_V * math.sqrt(3.0), "init_free_weight": 1.0,
        "reid_max_gap": None, "reach_gate": False, "imm_coast_after": None,
        "imm_init_acceleration": 10.0, "imm_tpm_period": scan_period, "imm_gating": cfg.imm_gating,
        "p_gate": cfg.p_gate,
    }  # fmt: skip
    if name == "kf":
        return common | {"motion": "cv", "q": cfg.kf_sigma**2}
    if name == "singer":
        model = Singer.from_maneuver(
            cfg.singer_tau, cfg.singer_a_max, cfg.singer_p_max, cfg.singer_p_0
        )
        return common | {
            "motion": "singer", "imm_singer_tau": model.tau, "imm_singer_sigma_m": model.sigma_m,
        }  # fmt: skip
    if name in ("imm2", "imm2-p22"):
        tpm = SOURCE_TPM_IMM2 if name == "imm2" else TYPICAL_TPM_IMM2
        return common | {"motion": "imm-pcwpa", "imm_tpm": list(tpm), "imm_mu0": [0.5, 0.5]}
    if name == "imm3":
        return common | {
            "motion": "imm-cv-singer-ct", "imm_q_cv": (G0 / 2) ** 2, "imm_singer_tau": 10.0,
            "imm_singer_sigma_m": 2 * G0, "imm_ct_sigma_a": 2.0, "imm_ct_sigma_omega": 0.02,
            "imm_tpm": list(IMM3_TPM), "imm_mu0": [1.0, 1.0, 1.0],
        }  # fmt: skip
    raise ValueError(f"filter {name!r} is not known")


def _scan_batch(scan):
    from skyfuse.schemas import PlotBatch

    alt = None if scan.altitude is None else scan.altitude.tolist()
    el = None if scan.elevation is None else scan.elevation.tolist()
    return PlotBatch(
        radar_id=scan.radar_id,
        scan=scan.scan,
        seq=scan.scan,
        time_start=int(scan.time_start),
        time_end=int(max(scan.time_end, scan.time.max(initial=scan.time_start))),
        time=scan.time.tolist(),
        range=scan.range.tolist(),
        azimuth=scan.azimuth.tolist(),
        altitude=alt,
        elevation=el,
    )


def crossing_run(cfg: CrossingEvalConfig, run: int) -> dict:
    """One Monte Carlo run: every filter over the same plots.

    At the first scan ≥ ``first_scan`` with two confirmed tracks, they are matched to
    targets 0 and 1 (optimal assignment by distance). Returns per filter: errors
    (n_scans, 2) of those two tracks (NaN once deleted); the nearest-confirmed-track error
    (n_scans,), RMS over targets; ``swapped``: at the last scan the track of a target
    follows the other target (is nearest to it, within ``follow_distance``); ``lost``: the
    track of a target was deleted or is farther than ``follow_distance`` from both;
    ``first_cross_scan``: the first scan at which a target's track is nearest the other
    target (None if never); and the track positions."""
    scans, times_ns, tpos, t0, site = _simulate(cfg, run)
    out = {}
    for name in cfg.filters:
        step = _stepper(name, cfg, site)
        t_start = time.process_time()
        out[name] = _score(cfg, step, scans, tpos)
        out[name]["cpu_s"] = time.process_time() - t_start
    return {"times_s": (times_ns - t0) * 1e-9, "truth": tpos, "filters": out}


def _simulate(cfg: CrossingEvalConfig, run: int):
    """Plots of run ``run`` converted to the system frame: [(z, R, t_ns)], scan times,
    truth positions (n_scans, 2, 2), start time (ns), the radar site."""
    from skyfuse.fusion.frames import SystemFrame, convert_plots
    from skyfuse.fusion.sim import Simulator, build_scenario

    seed = cfg.seed * 100_003 + run
    sc = build_scenario("crossing-4g", seed=cfg.seed, sigma_az_mrad=cfg.sigma_az_mrad)
    sim = Simulator(sc, seed=seed)
    frame = SystemFrame.from_spec(sc.frame)
    site = sc.sites[0]
    scans = []
    for scan in sim.scans():
        conv = convert_plots(frame, site, _scan_batch(scan)).select_valid()
        t_ns = int(np.rint(conv.time.mean())) if len(conv) else int(scan.time_end)
        scans.append((conv.z, conv.R, t_ns))
    times_ns = np.array([t for *_, t in scans], np.int64)
    truth = sim.truth_at(times_ns)
    tpos = np.stack([truth["x"], truth["y"]], axis=-1)  # (n_scans, 2 targets, 2)
    return scans, times_ns, tpos, sc.start_time, site


def _stepper(name: str, cfg: CrossingEvalConfig, site):
    """``step(z, R, t_ns) -> (ids, confirmed (n,) bool, positions (n, 2))`` of a filter: a
    :class:`fusion.tracker.Tracker` with the baseline's settings (:func:`baseline_settings`)
    or, for ``KIND:MOTION``, ``--tracker-config``'s with that kind and motion."""
    from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig

    if name in FILTER_HELP:
        settings = baseline_settings(name, cfg, site.scan_period)
    else:
        kind, _, motion = name.partition(":")
        settings = {}
        if cfg.tracker_config is not None:
            from skyfuse.services.runtime.config import load_toml

            settings = load_toml(cfg.tracker_config, "tracker")
        settings.update(tracker=kind, motion=motion, p_gate=cfg.p_gate)
    tracker = Tracker(TrackerConfig(**settings))

    def step(z, R, t_ns):
        out = tracker.step(MeasurementBatch(t_ns, "radar", z, R, float(site.p_detection), 0.0))
        return out.ids, out.confirmed, out.states[:, 0::2][:, :2]

    return step


def _score(cfg: CrossingEvalConfig, step, scans, tpos) -> dict:
    """Run one filter over the scans and score it against the truth (see crossing_run)."""
    n_scans = len(scans)
    err = np.full((n_scans, 2), np.nan)
    best = np.full(n_scans, np.nan)
    pos_hist = np.full((n_scans, 2, 2), np.nan)
    matched = None
    for s, (z, R, t_ns) in enumerate(scans):
        ids, confirmed, pos = step(z, R, t_ns)
        conf = np.flatnonzero(confirmed)
        if conf.size:
            d = np.linalg.norm(pos[conf][:, None, :] - tpos[s][None], axis=-1)
            best[s] = math.sqrt(float((d.min(axis=0) ** 2).mean()))
            if matched is None and s >= cfg.first_scan and conf.size >= 2:
                from scipy.optimize import linear_sum_assignment  # 0.5 s import: only when used

                r_idx, c_idx = linear_sum_assignment(d)
                matched = {int(c): int(ids[conf[r]]) for r, c in zip(r_idx, c_idx)}
        for tgt, tid in (matched or {}).items():
            where = np.flatnonzero(ids == tid)
            if where.size:
                pos_hist[s, tgt] = pos[where[0]]
                err[s, tgt] = float(np.linalg.norm(pos[where[0]] - tpos[s, tgt]))
    follows = _follows(pos_hist[-1], tpos[-1], cfg.follow_distance)
    if matched is None:
        follows = np.array([-1, -1])
    first_cross = None
    for k in range(n_scans):
        f_k = _follows(pos_hist[k], tpos[k], cfg.follow_distance)
        if any(f_k[a] == 1 - a for a in (0, 1)):
            first_cross = k
            break
    return {
        "err": err,
        "best": best,
        "swapped": bool(any(follows[a] == 1 - a for a in (0, 1))),
        "lost": bool((follows < 0).any()),
        "first_cross_scan": first_cross,
        "positions": pos_hist,
    }


def _follows(track_pos: np.ndarray, target_pos: np.ndarray, max_dist: float) -> np.ndarray:
    """For the track of each target (rows of track_pos, NaN if deleted): index of the
    target it is nearest to at the end, or −1 if deleted or farther than max_dist."""
    out = np.full(track_pos.shape[0], -1)
    for a in range(track_pos.shape[0]):
        if np.isnan(track_pos[a]).any():
            continue
        d = np.linalg.norm(target_pos - track_pos[a], axis=-1)
        if d.min() <= max_dist:
            out[a] = int(np.argmin(d))
    return out


def _runs_chunk(args: tuple[dict, list[int]]) -> list[dict]:
    cfg = CrossingEvalConfig.model_validate(args[0])
    return [crossing_run(cfg, r) for r in args[1]]


def evaluate_crossing(cfg: CrossingEvalConfig, progress: Callable[[int], None] | None = None):
    """All runs → summary dict (RMSE per scan per filter, swaps, configuration)."""
    runs = list(range(cfg.runs))
    results: list[dict] = []
    if cfg.workers == 1:
        for r in runs:
            results.append(crossing_run(cfg, r))
            if progress:
                progress(len(results))
    else:
        chunks = [runs[i :: cfg.workers * 4] for i in range(cfg.workers * 4)]
        payload = cfg.model_dump(mode="json")
        with ProcessPoolExecutor(cfg.workers) as ex:
            for part in ex.map(_runs_chunk, [(payload, c) for c in chunks if c]):
                results.extend(part)
                if progress:
                    progress(len(results))
    first = results[0]
    summary: dict = {
        "scenario": "crossing-4g",
        "scan_times_s": first["times_s"].round(3).tolist(),
        "first_scan": cfg.first_scan,
        "filters": {},
    }
    for name in cfg.filters:
        err = np.stack([r["filters"][name]["err"] for r in results])  # (runs, scans, 2)
        best = np.stack([r["filters"][name]["best"] for r in results])
        rmse_t = _nan_rms(err)  # (scans, 2)
        rmse_b = _nan_rms(best)
        scored = np.isfinite(err).sum(axis=0)
        swaps = sum(r["filters"][name]["swapped"] for r in results)
        lost = sum(r["filters"][name]["lost"] for r in results)
        t_s = first["times_s"]
        scored_scans = np.arange(t_s.size) >= cfg.first_scan
        windows = {
            "before_turn": scored_scans & (t_s < TURN_START_S),
            "turn": scored_scans & (t_s >= TURN_START_S) & (t_s < TURN_END_S + 4.0),
            "after_turn": t_s >= TURN_END_S + 4.0,
        }
        ok = sum(not (r["filters"][name]["swapped"] or r["filters"][name]["lost"]) for r in results)
        crossings = dict.fromkeys(windows, 0)
        for r in results:
            c = r["filters"][name]["first_cross_scan"]
            if c is not None:
                for k, w in windows.items():
                    crossings[k] += bool(w[c])
        summary["filters"][name] = {
            "description": filter_description(name),
            "rmse_target0": _clean(rmse_t[:, 0]),
            "rmse_target1": _clean(rmse_t[:, 1]),
            "rmse_nearest_track": _clean(rmse_b),
            "runs_scored_per_scan": scored[:, 0].tolist(),
            "mean_rmse_target0": {k: _mean(rmse_t[w, 0]) for k, w in windows.items()},
            "mean_rmse_nearest_track": {k: _mean(rmse_b[w]) for k, w in windows.items()},
            "swaps": int(swaps),
            "lost": int(lost),
            "both_kept": int(ok),
            "first_crossing_runs": crossings,
            "runs": len(results),
            "cpu_s": float(sum(r["filters"][name]["cpu_s"] for r in results)),
        }
    return summary, results


def _nan_rms(a: np.ndarray) -> np.ndarray:
    """RMS over runs (axis 0) ignoring NaN; NaN where no run has a value."""
    ok = np.isfinite(a)
    n = ok.sum(axis=0)
    total = np.where(ok, a, 0.0) ** 2
    return np.where(n > 0, np.sqrt(total.sum(axis=0) / np.maximum(n, 1)), np.nan)


def _clean(a: np.ndarray) -> list[float | None]:
    return [None if not np.isfinite(v) else round(float(v), 3) for v in a]


def _mean(a: np.ndarray) -> float | None:
    a = a[np.isfinite(a)]
    return round(float(a.mean()), 3) if a.size else None


# --------------------------------------------------------------------------------------
# outputs
# --------------------------------------------------------------------------------------
def markdown_table(summary: dict) -> str:
    names = list(summary["filters"])
    lines = [
        "| scan | t (s) | " + " | ".join(f"{n} RMSE₀ (m)" for n in names) + " |",
        "|---:|---:|" + "---:|" * len(names),
    ]
    for s, t in enumerate(summary["scan_times_s"]):
        vals = []
        for n in names:
            v = summary["filters"][n]["rmse_target0"][s]
            vals.append("–" if v is None else f"{v:.1f}")
        lines.append(f"| {s} | {t:.1f} | " + " | ".join(vals) + " |")
    lines.append("")
    lines.append(
        "| filter | RMSE₀ before / turn / after (m) | nearest-track RMSE before / turn / "
        "after (m) | swaps | lost | both kept | first crossing before / turn / after | runs |"
    )
    lines.append("|---|---:|---:|---:|---:|---:|---:|---:|")
    for n in names:
        f = summary["filters"][n]
        a = " / ".join(str(v) for v in f["mean_rmse_target0"].values())
        b = " / ".join(str(v) for v in f["mean_rmse_nearest_track"].values())
        c = " / ".join(str(v) for v in f["first_crossing_runs"].values())
        lines.append(
            f"| {n} | {a} | {b} | {f['swaps']} | {f['lost']} | {f['both_kept']} | {c} | "
            f"{f['runs']} |"
        )
    return "\n".join(lines) + "\n"


def write_figures(summary: dict, results: list[dict], out: Path, tag: str) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.asarray(summary["scan_times_s"])
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    for n, f in summary["filters"].items():
        for ax, key in zip(axes, ("rmse_target0", "rmse_target1", "rmse_nearest_track")):
            y = np.array([np.nan if v is None else v for v in f[key]])
            ax.plot(t, y, marker="o", ms=3, label=f"{n} (swaps {f['swaps']}/{f['runs']})")
    for ax, title in zip(
        axes, ("target 0 (track kept from initiation)", "target 1", "nearest confirmed track")
    ):
        ax.set_title(title)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("position RMSE (m)")
        ax.axvspan(34, 42, color="0.9")
        ax.set_yscale("log")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"crossing-4g, {tag}")
    fig.tight_layout()
    p1 = out / f"crossing-4g-rmse-{tag}.png"
    fig.savefig(p1, dpi=110)
    plt.close(fig)
    # trajectories of run 0
    r0 = results[0]
    names = list(summary["filters"])
    fig, axes = plt.subplots(1, len(names), figsize=(5 * len(names), 5), squeeze=False)
    for ax, n in zip(axes[0], names):
        tr = r0["truth"]
        for k, c in ((0, "C0"), (1, "C1")):
            ax.plot(tr[:, k, 0] / 1e3, tr[:, k, 1] / 1e3, "-", color=c, lw=1, label=f"target {k}")
            p = r0["filters"][n]["positions"][:, k]
            ax.plot(p[:, 0] / 1e3, p[:, 1] / 1e3, "x--", color=c, ms=4, label=f"track of {k}")
        ax.set_title(f"{n}: run 0" + (" (swapped)" if r0["filters"][n]["swapped"] else ""))
        ax.set_xlabel("east (km)")
        ax.set_ylabel("north (km)")
        ax.set_aspect("equal")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    p2 = out / f"crossing-4g-tracks-{tag}.png"
    fig.savefig(p2, dpi=110)
    plt.close(fig)
    return [p1, p2]


# --------------------------------------------------------------------------------------
# command
# --------------------------------------------------------------------------------------


def scenario_params(cfg: CrossingEvalConfig) -> dict:
    from skyfuse.fusion.sim import build_scenario

    return build_scenario("crossing-4g", seed=cfg.seed, sigma_az_mrad=cfg.sigma_az_mrad).params
