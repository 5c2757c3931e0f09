"""Track management: confirmation, termination and duplicate removal ([thesis] §7.1-7.2).

* Confirm when ψ_{k|k} ≥ τ_c (and the track had at least ``min_updates`` scans with a
  plot); confirmation is kept until termination (hysteresis).
* Terminate when ψ < τ_t.
* Or, with ``life_cycle = "m_of_n"``, by counting scans (the classical GNN life cycle of
  [MZD] §1: tracks not confirmed by new plots within a time window are deleted): confirm
  a tentative track with a plot in M of its first N scans in coverage (the scan that
  started it is one), delete it once M can no longer be reached, and end a confirmed
  track after ``max_misses`` consecutive scans without a plot.
* Duplicates: two tracks whose most likely plot in this batch is the same one and whose
  state estimates pass d² = Δx̂ᵀ (P₁ + P₂)⁻¹ Δx̂ < g_dup are one target (targets in
  formation keep their own plots and are not merged); the weaker is deleted
  and logged as merged into the other. "Weaker" ranks confirmed tracks above tentative
  ones (so a confirmed track's id survives), then by existence ([thesis] §7.1: keep
  the largest ψ). With ``established`` (``duplicate_survivor``), of two confirmed tracks
  the one with more scans with a plot survives with its id (the track number an operator
  has followed longest), ψ breaking ties; tentative pairs still by ψ.
"""

from __future__ import annotations

import numba
import numpy as np

from .store import Column, ColumnGroup


def to_confirm(
    psi: np.ndarray, confirmed: np.ndarray, updates: np.ndarray, tau_c: float, min_updates: int
) -> np.ndarray:
    """Tentative tracks that reach confirmation now."""
    return ~confirmed & (psi >= tau_c) & (updates >= min_updates)


def to_terminate(psi: np.ndarray, tau_t: float) -> np.ndarray:
    return psi < tau_t


def to_confirm_m_of_n(confirmed: np.ndarray, updates: np.ndarray, m: int) -> np.ndarray:
    """Tentative tracks with M scans with a plot: ``updates`` after the one that started
    them (a tentative track past its first N scans has been deleted already)."""
    return ~confirmed & (updates + 1 >= m)


def life_cycle_columns():
    """The per-track counters of the M-of-N life cycle (declared in the track store only
    when ``life_cycle = "m_of_n"``): ``scans``, the batches that saw the track (the one that
    started it included), and ``misses``, the consecutive ones of them without a plot."""
    return ColumnGroup(
        "life_cycle",
        (Column("scans", np.int64, fill=1, doc="batches that saw the track, its first included"),
         Column("misses", np.int64, fill=0, doc="consecutive batches without a plot")),
    )  # fmt: skip


def to_terminate_by_count(
    confirmed: np.ndarray,
    updates: np.ndarray,
    scans: np.ndarray,
    misses: np.ndarray,
    m_of_n: tuple[int, int],
    max_misses: int,
) -> np.ndarray:
    """Tentative tracks that cannot reach M plots in their first N ``scans`` any more
    (plots so far + scans left < M), and confirmed tracks with ``max_misses`` consecutive
    ``misses``."""
    m, n = m_of_n
    hopeless = ~confirmed & (updates + 1 + np.maximum(n - scans, 0) < m)
    return hopeless | (confirmed & (misses >= max_misses))


def shared_plot_pairs(tp_track: np.ndarray, tp_plot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct pairs (a, b), a < b, of tracks with a common plot in ``tp_plot``, in
    lexicographic order (one compiled pass, :func:`_shared_pairs`)."""
    if len(tp_track) < 2:
        e = np.zeros(0, np.int64)
        return e, e
    c = np.ascontiguousarray
    return _shared_pairs(c(tp_track, dtype=np.int64), c(tp_plot, dtype=np.int64))


@numba.njit(cache=True, nogil=True)
def _shared_pairs(track, plot):
    """Rows sorted by (plot, track); every pair of tracks within a plot's run; the
    distinct pairs sorted."""
    n = len(track)
    span = track.max() + 1
    key = np.empty(n, np.int64)
    for r in range(n):
        key[r] = plot[r] * span + track[r]
    order = np.argsort(key)
    total = 0
    lo = 0
    for s in range(1, n + 1):
        if s == n or plot[order[s]] != plot[order[lo]]:
            total += (s - lo) * (s - lo - 1) // 2
            lo = s
    pair = np.empty(total, np.int64)
    p = 0
    lo = 0
    for s in range(1, n + 1):
        if s == n or plot[order[s]] != plot[order[lo]]:
            for i in range(lo, s):
                for j in range(i + 1, s):
                    a, b = track[order[i]], track[order[j]]
                    if a != b:
                        pair[p] = min(a, b) * span + max(a, b)
                        p += 1
            lo = s
    pair = np.unique(pair[:p])
    return pair // span, pair % span


def duplicate_rank(
    confirmed: np.ndarray, updates: np.ndarray | None, psi: np.ndarray
) -> np.ndarray:
    """Rank (n,) of tracks for duplicate removal, larger survives: confirmed first, then
    ψ; with ``updates`` (the ``established`` rule) confirmed tracks by their number of
    scans with a plot before ψ. Exact ties go to the earlier row (the older track)."""
    n = len(psi)
    scans = np.zeros(n) if updates is None else np.where(confirmed, updates, 0)
    order = np.lexsort((-np.arange(n), psi, scans, confirmed))
    rank = np.empty(n, np.int64)
    rank[order] = np.arange(n)
    return rank


def duplicates(
    a: np.ndarray,
    b: np.ndarray,
    x: np.ndarray,
    P: np.ndarray,
    psi: np.ndarray,
    confirmed: np.ndarray,
    updates: np.ndarray | None,
    g_dup: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(loser, winner) rows among candidate pairs (a, b) whose estimates coincide; the
    winner has the larger :func:`duplicate_rank` (``updates`` None: by ψ alone)."""
    if len(a) == 0:
        e = np.zeros(0, np.int64)
        return e, e
    dx = x[a] - x[b]
    S = P[a] + P[b]
    d2 = np.einsum("pi,pi->p", dx, np.linalg.solve(S, dx[..., None])[..., 0])
    close = d2 < g_dup
    a, b = a[close], b[close]
    rank = duplicate_rank(confirmed, updates, psi)
    a_wins = rank[a] >= rank[b]
    loser = np.where(a_wins, b, a)
    winner = np.where(a_wins, a, b)
    # one removal per loser: keep its strongest winner
    order = np.lexsort((-rank[winner], loser))
    first = np.concatenate(([True], loser[order][1:] != loser[order][:-1])) if len(order) else order
    return loser[order][first], winner[order][first]
