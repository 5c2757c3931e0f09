"""Per-scan measures of multi-target tracking over Monte Carlo runs (spec 03 §4).

* ``ctt_rate``: the confirmed-true-track (CTT) diagram: per scan, the percentage of
  (run, target) pairs present at that scan with at least one confirmed true track
  (each target counted once, duplicates do not add).
* ``confirmed_false_tracks``: per scan, the cumulative number of distinct false tracks
  that reached confirmation, summed over runs. A track is counted once, at the first
  (run, scan) in which it is confirmed while labelled false; this includes a confirmed
  true track that was lost and became false (it is then a confirmed track on no target).
  A false track carried over into the next run keeps its id and is not counted again.
* ``rmse_confirmed_true``: per scan, the RMS Euclidean position error of all confirmed
  true tracks with respect to their target (duplicates included), over runs. Spec 03 §4
  leaves Euclidean vs per-axis open [A]: this is the Euclidean (radial) RMSE; the
  per-axis RMSE is this divided by √d.

Inputs are ``history.TrackHistory`` and ``history.TruthHistory`` columns; positions in
metres; ``scans`` the scan numbers to report (e.g. ``np.arange(1, 41)``).
"""

from __future__ import annotations

import numpy as np

from .history import TrackHistory, TruthHistory, joint_keys


def _scan_index(scans: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of each value in the sorted-unique ``scans`` and a mask of values found."""
    idx = np.searchsorted(scans, values)
    ok = idx < len(scans)
    ok[ok] = scans[idx[ok]] == values[ok]
    return idx, ok


def _check_scans(scans: np.ndarray) -> np.ndarray:
    s = np.asarray(scans)
    if s.ndim != 1 or not np.issubdtype(s.dtype, np.integer) or np.any(np.diff(s) <= 0):
        raise ValueError(f"scans: {s!r}: must be a strictly increasing 1-D integer array")
    return s.astype(np.int64)


def ctt_rate(tracks: TrackHistory, truth: TruthHistory, scans: np.ndarray) -> np.ndarray:
    """CTT rate per scan, percent (NaN at a scan with no target present)."""
    scans = _check_scans(scans)
    ct = tracks.confirmed_true
    tk, gk = joint_keys(
        (tracks.run[ct], tracks.scan[ct], tracks.label[ct]),
        (truth.run, truth.scan, truth.target_id),
    )
    hit = np.isin(gk, tk)
    idx, ok = _scan_index(scans, truth.scan)
    present = np.bincount(idx[ok], minlength=len(scans)).astype(float)
    covered = np.bincount(idx[ok], weights=hit[ok].astype(float), minlength=len(scans))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(present > 0, 100.0 * covered / present, np.nan)


def confirmed_false_tracks(tracks: TrackHistory, scans: np.ndarray) -> np.ndarray:
    """Cumulative count of distinct confirmed false tracks per scan, summed over runs (int)."""
    scans = _check_scans(scans)
    cf = tracks.confirmed & (tracks.label < 0)
    run, scan, tid = tracks.run[cf], tracks.scan[cf], tracks.track_id[cf]
    order = np.lexsort((scan, run))
    _, first = np.unique(tid[order], return_index=True)
    first_scan = scan[order][first]
    idx, ok = _scan_index(scans, first_scan)
    # A first confirmation before the first reported scan still counts from the start.
    before = first_scan < scans[0] if len(scans) else np.zeros(0, bool)
    idx = np.where(before, 0, idx)
    ok = ok | before
    return np.cumsum(np.bincount(idx[ok], minlength=len(scans))).astype(np.int64)


def rmse_confirmed_true(
    tracks: TrackHistory, truth: TruthHistory, scans: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """RMS position error of confirmed true tracks per scan (metres, NaN where none) and the
    number of track rows it averages. Rows whose target is absent at that scan are skipped."""
    scans = _check_scans(scans)
    if tracks.position.shape[1] != truth.position.shape[1] and len(tracks) and len(truth):
        raise ValueError(
            f"position: tracks have dimension {tracks.position.shape[1]}, truth "
            f"{truth.position.shape[1]}: must match"
        )
    ct = tracks.confirmed_true
    tk, gk = joint_keys(
        (tracks.run[ct], tracks.scan[ct], tracks.label[ct]),
        (truth.run, truth.scan, truth.target_id),
    )
    order = np.argsort(gk, kind="stable")
    pos_in = np.searchsorted(gk[order], tk)
    found = pos_in < len(gk)
    found[found] = gk[order][pos_in[found]] == tk[found]
    err = tracks.position[ct][found] - truth.position[order][pos_in[found]]
    sq = np.einsum("ij,ij->i", err, err)
    idx, ok = _scan_index(scans, tracks.scan[ct][found])
    count = np.bincount(idx[ok], minlength=len(scans))
    total = np.bincount(idx[ok], weights=sq[ok], minlength=len(scans))
    with np.errstate(invalid="ignore", divide="ignore"):
        rmse = np.where(count > 0, np.sqrt(total / np.maximum(count, 1)), np.nan)
    return rmse, count.astype(np.int64)
