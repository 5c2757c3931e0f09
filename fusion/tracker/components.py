"""Track mixtures in flat arrays: Singer N-scan merge and pruning ([thesis] ch. 5); the moment
matching itself is :mod:`fusion.filters.moment_matching`.

Every track is a Gaussian mixture {ξ^c, x̂^c, P^c, h^c}. All components of all tracks
live in one :class:`Mixture`: ``track`` (C,) says which track row a component belongs to,
``hist`` (C, N) holds the ids of the plots the component used over the last N scans
(0 = no plot), most recent first. Grouped sums are ``np.bincount`` calls over columns,
so no Python loop runs over components.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from skyfuse.fusion.filters.moment_matching import moment_match, segment_sum

__all__ = [
    "Mixture",
    "components_per_track",
    "history_groups",
    "moment_match",
    "normalise",
    "prune",
    "prune_indices",
    "segment_sum",
    "singer_merge",
    "track_estimates",
]


@dataclass
class Mixture:
    """Flat component store: track (C,), w (C,), x (C, d), P (C, d, d), hist (C, N)."""

    track: np.ndarray
    w: np.ndarray
    x: np.ndarray
    P: np.ndarray
    hist: np.ndarray

    @classmethod
    def empty(cls, dim: int, depth: int) -> Mixture:
        return cls(
            np.zeros(0, np.int64),
            np.zeros(0),
            np.zeros((0, dim)),
            np.zeros((0, dim, dim)),
            np.zeros((0, depth), np.int64),
        )

    def __len__(self) -> int:
        return len(self.w)

    def take(self, idx: np.ndarray) -> Mixture:
        return Mixture(self.track[idx], self.w[idx], self.x[idx], self.P[idx], self.hist[idx])

    @staticmethod
    def concat(parts: list[Mixture]) -> Mixture:
        return Mixture(
            np.concatenate([p.track for p in parts]),
            np.concatenate([p.w for p in parts]),
            np.concatenate([p.x for p in parts]),
            np.concatenate([p.P for p in parts]),
            np.concatenate([p.hist for p in parts]),
        )


def singer_merge(mix: Mixture) -> Mixture:
    """Singer N-scan memory ([thesis] §5.3): merge, per track, all components whose
    last-N-scan plot histories are equal. Depth 0 (no history columns) merges every track
    into one Gaussian, i.e. IPDA. Resulting counts: C_k = 1+m_k (N=1),
    (1+m_k)(1+m_{k−1}) (N=2) when every component selects every plot (5.26, 5.1a)."""
    if len(mix) == 0:
        return mix
    order = np.argsort(mix.track, kind="stable")
    ts = mix.track[order]
    if len(ts) < 2 or (ts[1:] > ts[:-1]).all():
        # one component per track (GNN, IPDA): each is its own group, in track order
        out = mix.take(order)
        out.P = 0.5 * (out.P + out.P.swapaxes(1, 2))
        return out
    inv, uniq = history_groups(mix.track, mix.hist)
    W, xm, Pm = moment_match(mix.w, mix.x, mix.P, inv, len(uniq))
    return Mixture(uniq[:, 0].copy(), W, xm, Pm, uniq[:, 1:].copy())


def normalise(mix: Mixture, ntracks: int) -> Mixture:
    """Scale weights so they sum to 1 within each track (Σ_c ξ^c = 1, [thesis] (4.71))."""
    if len(mix) == 0:
        return mix
    tot = np.bincount(mix.track, weights=mix.w, minlength=ntracks)
    mix.w = mix.w / np.where(tot[mix.track] > 0, tot[mix.track], 1.0)
    return mix


def prune_indices(
    track: np.ndarray, w: np.ndarray, threshold: float, max_per_track: int, ntracks: int
) -> tuple[np.ndarray, np.ndarray]:
    """Which components survive pruning, and their renormalised weights: delete ξ <
    ``threshold`` (keeping each track's strongest), keep at most ``max_per_track`` per
    track by weight ([IMPL]). Returns (kept indices, weights)."""
    if len(w) == 0:
        return np.zeros(0, np.int64), w
    if len(track) < 2 or (track[1:] > track[:-1]).all():
        # one component per track: it is kept, its weight normalised (twice, as below)
        wn = w / np.where(w > 0, w, 1.0)
        return np.arange(len(w)), wn / np.where(wn > 0, wn, 1.0)
    tot = np.bincount(track, weights=w, minlength=ntracks)
    w = w / np.where(tot[track] > 0, tot[track], 1.0)
    order = np.lexsort((-w, track))
    t_sorted = track[order]
    first = np.searchsorted(t_sorted, t_sorted, side="left")
    rank = np.arange(len(order)) - first
    keep_sorted = (rank < max_per_track) & ((w[order] >= threshold) | (rank == 0))
    keep = np.sort(order[keep_sorted])
    wk, tk = w[keep], track[keep]
    tot = np.bincount(tk, weights=wk, minlength=ntracks)
    return keep, wk / np.where(tot[tk] > 0, tot[tk], 1.0)


def prune(mix: Mixture, threshold: float, max_per_track: int, ntracks: int) -> Mixture:
    """:func:`prune_indices` applied to a :class:`Mixture`."""
    if len(mix) == 0:
        return mix
    keep, w = prune_indices(mix.track, mix.w, threshold, max_per_track, ntracks)
    out = mix.take(keep)
    out.w = w
    return out


def history_groups(track: np.ndarray, hist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Singer N-scan groups: (group label per component, unique (track, hist) rows),
    grouped as ``np.unique(keys, axis=0)`` would (lexicographic), by one lexsort."""
    keys = np.column_stack([track, hist])
    if len(track) < 2 or (track[1:] > track[:-1]).all():  # one component per track
        return np.arange(len(track)), keys
    order = np.lexsort(keys.T[::-1])
    ks = keys[order]
    new = np.concatenate(([True], (ks[1:] != ks[:-1]).any(axis=1)))
    inv = np.empty(len(order), np.int64)
    inv[order] = np.cumsum(new) - 1
    return inv, ks[new]


def track_estimates(mix: Mixture, ntracks: int) -> tuple[np.ndarray, np.ndarray]:
    """Moment-matched track output x̂ = Σξ x̂^c, P = Σξ(P^c + spread) (4.66-4.68)."""
    _, x, P = moment_match(mix.w, mix.x, mix.P, mix.track, ntracks)
    return x, P


def components_per_track(mix: Mixture, ntracks: int) -> np.ndarray:
    return np.bincount(mix.track, minlength=ntracks)
