"""GOSPA: generalised optimal sub-pattern assignment metric, per scan and over time.

The evaluation reports OSPA/GOSPA over time with a track-switch term (docs/how-to/evaluate.md).

Per scan (Rahmathullah, García-Fernández & Svensson, "Generalized optimal sub-pattern
assignment metric", FUSION 2017, Def. 1), for truth X = {x_1..x_n}, estimates
Y = {y_1..y_m}, n <= m (otherwise swap the roles), cut-off c > 0, order 1 <= p < ∞ and
0 < α <= 2::

    d_p^(c,α)(X, Y) = ( min_π Σ_{i=1..n} d^(c)(x_i, y_π(i))^p  +  c^p/α · (m − n) )^(1/p)

with d^(c)(x, y) = min(‖x − y‖, c). For α = 2 this equals the optimal *sub*-assignment
form (ibid., Prop. 1)::

    d_p^(c,2)(X, Y) = ( min_γ Σ_{(i,j)∈γ} ‖x_i − y_j‖^p + c^p/2 · (n + m − 2|γ|) )^(1/p)

where γ ranges over partial assignments with every assigned distance < c; so the p-th power
splits exactly into **localisation** (assigned pairs), **missed** (c^p/2 per unassigned truth)
and **false** (c^p/2 per unassigned estimate). An assigned pair at distance >= c costs
c^p = c^p/2 + c^p/2 and is reported as one missed and one false target. The optimal
assignment is exact, from ``scipy.optimize.linear_sum_assignment`` on min(D, c)^p.

Over time, the track-switch term follows trajectory GOSPA (García-Fernández, Rahmathullah &
Svensson, "A metric on the space of finite sets of trajectories for evaluation of
multi-target tracking algorithms", IEEE TSP 68, 2020, Def. 2): for switching penalty γ > 0
the p-th power of the metric gains γ^p/2 · s(π_{k−1}, π_k) per scan, where a truth whose
assignment changes from one track to another is a **full switch** (s += 1) and one that
changes between a track and no track is a **half switch** (s += 1/2). Trajectory GOSPA
minimises over the whole assignment sequence (a linear program); here, as in MATLAB's
``trackGOSPAMetric`` and Stone Soup's ``GOSPAMetric(switching_penalty=...)``, the
assignment of each scan is the per-scan optimum above and switches are counted between
consecutive scans, so the value is an upper bound of trajectory GOSPA. Counting rule
(per truth id, over the scans where that truth is present):

* a truth that is unassigned before its first assignment is not charged (a track that
  starts late is already charged as missed);
* scans where the truth is absent leave its last assignment unchanged;
* last track j → track j' ≠ j: full switch; j → unassigned or unassigned → j: half switch.

Units: positions in metres (any consistent unit); every reported GOSPA quantity
``localisation``, ``missed``, ``false``, ``switching`` is a contribution to the **p-th
power** of the distance (units metres^p), so ``distance**p == localisation + missed +
false`` (+ ``switching`` over time).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .point_pattern import check_cutoff_and_order, distance_matrix, optimal_assignment, pair_points

UNASSIGNED = -1


@dataclass(frozen=True)
class GospaResult:
    """GOSPA of one scan.

    distance: d_p^(c,α)(X, Y), metres.
    localisation, missed, false: contributions to distance**p (metres^p); for α = 2 they are
        Σ‖x_i − y_j‖^p over assigned pairs, c^p/2·n_missed, c^p/2·n_false. For α ≠ 2 the
        decomposition is not defined by the paper: localisation then holds Σ min(d, c)^p
        over the min(n, m) assigned pairs and missed/false the c^p/α·|m − n| term.
    assignment: (n,) index into the estimates for each truth, ``UNASSIGNED`` (−1) if none.
    n_missed, n_false: numbers of unassigned truths and estimates.
    """

    distance: float
    localisation: float
    missed: float
    false: float
    assignment: np.ndarray
    n_missed: int
    n_false: int


def gospa(
    truth_xy: np.ndarray,
    est_xy: np.ndarray,
    c: float,
    p: float = 2.0,
    alpha: float = 2.0,
) -> GospaResult:
    """GOSPA between truth positions ``(n, d)`` and estimated positions ``(m, d)``.

    ``c`` is the cut-off distance (metres), ``p`` the order (>= 1), ``alpha`` in (0, 2]
    (2 gives the localisation/missed/false decomposition). Either set may be empty.
    Raises ``ValueError`` for non-finite or mis-shaped positions or bad parameters."""
    check_cutoff_and_order(c, p)
    if not (0 < alpha <= 2):
        raise ValueError(f"alpha = {alpha}: must be in (0, 2]")
    x, y = pair_points(truth_xy, est_xy)
    n, m = len(x), len(y)
    dist = distance_matrix(x, y)
    rows, cols, _ = optimal_assignment(dist, c, p)
    assignment = np.full(n, UNASSIGNED, dtype=np.intp)
    cp = float(c) ** p
    if alpha == 2:
        keep = dist[rows, cols] < c
        rows, cols = rows[keep], cols[keep]
        assignment[rows] = cols
        localisation = float(np.sum(dist[rows, cols] ** p))
        n_missed, n_false = n - len(rows), m - len(rows)
        missed, false = cp / 2 * n_missed, cp / 2 * n_false
    else:
        assignment[rows] = cols
        localisation = float(np.sum(np.minimum(dist[rows, cols], c) ** p))
        n_missed, n_false = max(n - m, 0), max(m - n, 0)
        missed, false = cp / alpha * n_missed, cp / alpha * n_false
    total = localisation + missed + false
    return GospaResult(
        distance=float(total ** (1.0 / p)),
        localisation=localisation,
        missed=missed,
        false=false,
        assignment=assignment,
        n_missed=int(n_missed),
        n_false=int(n_false),
    )


@dataclass(frozen=True)
class GospaOverTime:
    """GOSPA per scan with the switch term; all arrays have one entry per scan (length K).

    distance, localisation, missed, false, n_missed, n_false: per-scan GOSPA (``gospa``).
    assigned_track: list of (n_k,) arrays: the track id assigned to each truth of scan k
        (in the order of ``truth_ids[k]``), ``UNASSIGNED`` (−1) if none.
    full_switches, half_switches: switches counted between scan k−1 and scan k (0 at k=0).
    switching: γ^p/2 · (full + half/2), the switch contribution to the p-th power (metres^p).
    distance_with_switching: (distance^p + switching)^(1/p) per scan.
    p: the order used, so that ``total`` can be formed.
    """

    distance: np.ndarray
    localisation: np.ndarray
    missed: np.ndarray
    false: np.ndarray
    n_missed: np.ndarray
    n_false: np.ndarray
    assigned_track: list[np.ndarray]
    full_switches: np.ndarray
    half_switches: np.ndarray
    switching: np.ndarray
    distance_with_switching: np.ndarray
    p: float

    @property
    def total(self) -> float:
        """Whole-sequence value (Σ_k distance_k^p + Σ_k switching_k)^(1/p), metres
        (the trajectory-GOSPA form evaluated on the per-scan assignments)."""
        return float((np.sum(self.distance**self.p) + np.sum(self.switching)) ** (1.0 / self.p))


def _as_ids(name: str, ids: np.ndarray, n: int) -> np.ndarray:
    arr = np.asarray(ids)
    if arr.size == 0:
        arr = arr.astype(np.int64).reshape(0)
    if arr.ndim != 1 or len(arr) != n:
        raise ValueError(f"{name}: shape {arr.shape}: must be ({n},), one id per position row")
    if not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"{name}: dtype {arr.dtype}: ids must be integers")
    if np.any(arr < 0):
        raise ValueError(f"{name}: id {int(arr[arr < 0][0])}: ids must be >= 0")
    if len(np.unique(arr)) != len(arr):
        raise ValueError(f"{name}: ids {arr.tolist()}: must be unique within a scan")
    return arr.astype(np.int64)


def gospa_over_time(
    truth_ids: Sequence[np.ndarray],
    truth_pos: Sequence[np.ndarray],
    track_ids: Sequence[np.ndarray],
    track_pos: Sequence[np.ndarray],
    c: float,
    p: float = 2.0,
    alpha: float = 2.0,
    switch_penalty: float = 0.0,
) -> GospaOverTime:
    """GOSPA for every scan k = 0..K−1 plus the track-switch term.

    Inputs are per-scan sequences of equal length K: ``truth_ids[k]`` (n_k,) non-negative
    integer target ids with positions ``truth_pos[k]`` (n_k, d); ``track_ids[k]`` (m_k,)
    non-negative integer track ids with positions ``track_pos[k]`` (m_k, d). ``switch_penalty``
    is γ (metres); with γ > 0, ``alpha`` must be 2 (the switch term is defined for α = 2).
    See the module docstring for the switch-counting rule."""
    K = len(truth_ids)
    for name, seq in (("truth_pos", truth_pos), ("track_ids", track_ids), ("track_pos", track_pos)):
        if len(seq) != K:
            raise ValueError(f"{name}: {len(seq)} scans: must equal len(truth_ids) = {K}")
    if not (np.isfinite(switch_penalty) and switch_penalty >= 0):
        raise ValueError(f"switch_penalty = {switch_penalty}: must be finite and >= 0")
    if switch_penalty > 0 and alpha != 2:
        raise ValueError(f"alpha = {alpha}: the switch term needs alpha = 2")
    out = {k: np.zeros(K) for k in ("distance", "localisation", "missed", "false")}
    n_missed = np.zeros(K, dtype=np.int64)
    n_false = np.zeros(K, dtype=np.int64)
    full = np.zeros(K, dtype=np.int64)
    half = np.zeros(K, dtype=np.int64)
    assigned_track: list[np.ndarray] = []
    last: dict[int, int] = {}  # truth id -> last recorded track id (or UNASSIGNED)
    for k in range(K):
        tp = np.asarray(truth_pos[k], dtype=np.float64)
        ep = np.asarray(track_pos[k], dtype=np.float64)
        tid = _as_ids(f"truth_ids[{k}]", truth_ids[k], len(tp))
        eid = _as_ids(f"track_ids[{k}]", track_ids[k], len(ep))
        r = gospa(tp, ep, c=c, p=p, alpha=alpha)
        out["distance"][k], out["localisation"][k] = r.distance, r.localisation
        out["missed"][k], out["false"][k] = r.missed, r.false
        n_missed[k], n_false[k] = r.n_missed, r.n_false
        got = np.full(len(tid), UNASSIGNED, dtype=np.int64)
        hit = r.assignment >= 0
        got[hit] = eid[r.assignment[hit]]
        assigned_track.append(got)
        for truth, track in zip(tid.tolist(), got.tolist()):
            if truth not in last:
                if track != UNASSIGNED:
                    last[truth] = track
                continue
            before = last[truth]
            if before != track:
                if before != UNASSIGNED and track != UNASSIGNED:
                    full[k] += 1
                else:
                    half[k] += 1
                last[truth] = track
    switching = float(switch_penalty) ** p / 2.0 * (full + 0.5 * half)
    return GospaOverTime(
        distance=out["distance"],
        localisation=out["localisation"],
        missed=out["missed"],
        false=out["false"],
        n_missed=n_missed,
        n_false=n_false,
        assigned_track=assigned_track,
        full_switches=full,
        half_switches=half,
        switching=switching,
        distance_with_switching=(out["distance"] ** p + switching) ** (1.0 / p),
        p=float(p),
    )
