"""Measures of one variant's Monte Carlo histories ([thesis] ch. 7): the retention row, the
CTT curve, the cumulative confirmed false tracks, the RMSE of confirmed true tracks with
its posterior Cramér–Rao floor (:mod:`.bound`, Tichavský et al. 1998) and GOSPA per scan, as plain
JSON-ready values (lists with ``None`` for NaN).

Two counts of confirmed false tracks are reported:

* ``false_tracks``: :func:`fusion.metrics.mtt_measures.confirmed_false_tracks`, every
  track ever confirmed while labelled false, including a confirmed true track that lost
  its target (it is then a confirmed track on no target until terminated);
* ``false_at_confirmation``: tracks labelled false **at the scan they were confirmed**
  (:func:`false_at_confirmation`), the reading of the thesis's "false tracks that reached
  confirmation" used for the ψ_init calibration: ψ_init controls how fast a false track
  reaches confirmation (false-track discrimination), while the losses of true tracks are
  a retention matter (they show in nLost).
"""

from __future__ import annotations

import math

import numpy as np
from skyfuse.fusion.metrics.history import TrackHistory, TruthHistory
from skyfuse.fusion.metrics.mtt_measures import (
    confirmed_false_tracks,
    ctt_rate,
    gospa_curves,
    rmse_confirmed_true,
)
from skyfuse.fusion.metrics.retention import retention_counts

from .bound import pcrlb_curves, position_bound_by_age, scenario_bound_model
from .experiment import Experiment, Variant
from .runner import RunBlock


def _clean(a: np.ndarray, nd: int = 3) -> list[float | None]:
    return [None if not math.isfinite(float(v)) else round(float(v), nd) for v in a]


def false_at_confirmation(tracks: TrackHistory, scans: np.ndarray) -> np.ndarray:
    """Cumulative count per scan (summed over runs) of tracks whose label was false at
    their first confirmed row; a track confirmed before ``scans[0]`` counts from the start.
    Tracks carried over from an earlier run keep their first confirmation."""
    scans = np.asarray(scans, dtype=np.int64)
    born = false_at_confirmation_rows(tracks)
    idx = np.searchsorted(scans, tracks.scan[born])
    idx = np.clip(idx, 0, len(scans))
    keep = idx < len(scans)
    return np.cumsum(np.bincount(idx[keep], minlength=len(scans))).astype(np.int64)


def false_at_confirmation_rows(tracks: TrackHistory) -> np.ndarray:
    """Row indices of the first confirmed row of every track whose label was false there
    (the tracks :func:`false_at_confirmation` counts; a carried track once)."""
    c = np.flatnonzero(tracks.confirmed)
    order = c[np.lexsort((tracks.scan[c], tracks.run[c]))]
    _, first = np.unique(tracks.track_id[order], return_index=True)
    rows = order[first]
    return rows[tracks.label[rows] < 0]


def false_origin(tracks: TrackHistory, truth: TruthHistory) -> dict:
    """Where the tracks false at confirmation are: per such track the distance
    (m) at its confirming scan to the nearest target of the same run and scan (∞: no
    target), and whether it is labelled true within the next 3 scans of its run. A track
    on a target but failing the labelling test (7.1) at confirmation is near a target; a
    track of clutter is not."""
    rows = false_at_confirmation_rows(tracks)
    dist = np.full(len(rows), np.inf)
    later = np.zeros(len(rows), bool)
    key_t = truth.run * (1 << 32) + truth.scan
    for i, r in enumerate(rows):
        m = key_t == tracks.run[r] * (1 << 32) + tracks.scan[r]
        if m.any():
            dist[i] = np.linalg.norm(truth.position[m] - tracks.position[r], axis=1).min()
        nxt = (
            (tracks.track_id == tracks.track_id[r])
            & (tracks.run == tracks.run[r])
            & (tracks.scan > tracks.scan[r])
            & (tracks.scan <= tracks.scan[r] + 3)
        )
        later[i] = bool((tracks.label[nxt] >= 0).any())
    return {"distance_m": dist, "true_within_3_scans": later}


def _bound(model: dict, scans: np.ndarray) -> np.ndarray:
    """Position bound B(k), k = 1..len(scans), of ``bound.scenario_bound_model``."""
    m = model
    n = max(len(scans), 1)
    return position_bound_by_age(n, m["period"], m["q"], m["sigma2"], m["p_detection"])


def summarise(block: RunBlock, exp: Experiment, variant: Variant, psi_init: float) -> dict:
    """Row (retention keys of ``fusion.metrics.retention.ROW_KEYS`` plus run counts and
    ψ_init) and per-scan curves of one variant. Scans are those of the truth history."""
    scans = np.unique(block.truth.scan)
    counts = retention_counts(
        block.tracks,
        block.merged_run,
        block.merged_track_id,
        block.merged_scan,
        k_start=exp.k_start,
        k_end=exp.k_end,
        cpu_s=block.cpu_s,
    )
    row = counts.row(variant.tracker, variant.depth)
    false = confirmed_false_tracks(block.tracks, scans)
    born = false_at_confirmation(block.tracks, scans)
    rmse, n_rmse = rmse_confirmed_true(block.tracks, block.truth, scans)
    g = gospa_curves(block.tracks, block.truth, scans, c=exp.gospa_c, p=exp.gospa_p)
    model = scenario_bound_model(exp)
    floor, floor_targets = pcrlb_curves(block.tracks, block.truth, scans, _bound(model, scans))
    floor_detected, _ = pcrlb_curves(
        block.tracks, block.truth, scans, _bound({**model, "p_detection": 1.0}, scans)
    )
    runs = len(np.unique(block.runs))
    row.update(
        {
            "psi_init": psi_init,
            "runs": runs,
            "false_tracks": int(false[-1]) if len(false) else 0,
            "false_tracks_per_500_runs": round(float(false[-1]) * 500.0 / runs, 2)
            if len(false) and runs
            else 0.0,
            "false_at_confirmation": int(born[-1]) if len(born) else 0,
            "false_at_confirmation_per_500_runs": round(float(born[-1]) * 500.0 / runs, 2)
            if len(born) and runs
            else 0.0,
            "cpu_ms_per_run": round(1e3 * block.cpu_s / max(runs, 1), 3),
            "gospa_mean": round(float(np.mean(g.distance)), 3),
            "carried_false_tracks_mean": round(float(np.mean(block.carried)), 3)
            if len(block.carried)
            else 0.0,
        }
    )
    curves = {
        "scans": scans.tolist(),
        "ctt_percent": _clean(ctt_rate(block.tracks, block.truth, scans), 2),
        "false_tracks_cumulative": false.tolist(),
        "false_at_confirmation_cumulative": born.tolist(),
        "rmse_m": _clean(rmse),
        "rmse_rows": n_rmse.tolist(),
        "pcrlb_m": _clean(floor),
        "pcrlb_targets_m": _clean(floor_targets),
        "pcrlb_all_detected_m": _clean(floor_detected),
        "pcrlb_model": model,
        "gospa_m": _clean(g.distance),
        "gospa_localisation": _clean(g.localisation),
        "gospa_missed": _clean(g.missed),
        "gospa_false": _clean(g.false),
        "gospa_switches": g.full_switches.tolist(),
    }
    return {"row": row, "curves": curves}
